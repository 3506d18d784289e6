/* Small dense linear algebra for the FMUs: row-major n x n (or n x m) matrices of double.
 * Sizes are a few dozen; clarity over blocking. No allocation: callers pass workspaces. */
#ifndef RAILCAL_LINALG_H
#define RAILCAL_LINALG_H

#include <stddef.h>

/* C = A (n x k) * B (k x m) */
void la_matmul(int n, int k, int m, const double *A, const double *B, double *C);
/* y = A (n x m) * x + beta * y (with beta = 0, y is only written) */
void la_matvec_acc(int n, int m, const double *A, const double *x, double beta, double *y);
/* LU factorisation with partial pivoting of A (n x n) in place; 0 on success, -1 if singular. */
int la_lu(int n, double *A, int *piv);
/* Solve A X = B for m right-hand sides (B n x m, overwritten by X) with the factors of la_lu. */
void la_lu_solve(int n, int m, const double *LU, const int *piv, double *B);
/* exp(A) of A (n x n) into E by balancing, then scaling and squaring with the [13/13] Pade
 * approximant (Higham, SIAM J. Matrix Anal. Appl. 26 (2005) 1179-1193). work: 7 n^2 + n
 * doubles, piv: n.
 * Returns 0, or -1 when A is not finite or the Pade denominator is singular. */
int la_expm(int n, const double *A, double *E, double *work, int *piv);

#endif
