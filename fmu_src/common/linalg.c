#include "linalg.h"

#include <math.h>
#include <string.h>

void la_matmul(int n, int k, int m, const double *A, const double *B, double *C) {
    for (int i = 0; i < n; i++) {
        double *c = C + (size_t)i * m;
        for (int j = 0; j < m; j++) c[j] = 0.0;
        for (int l = 0; l < k; l++) {
            const double a = A[(size_t)i * k + l];
            if (a == 0.0) continue;
            const double *b = B + (size_t)l * m;
            for (int j = 0; j < m; j++) c[j] += a * b[j];
        }
    }
}

void la_matvec_acc(int n, int m, const double *A, const double *x, double beta, double *y) {
    for (int i = 0; i < n; i++) {
        const double *a = A + (size_t)i * m;
        double s = 0.0;
        for (int j = 0; j < m; j++) s += a[j] * x[j];
        y[i] = beta == 0.0 ? s : beta * y[i] + s; /* y may be uninitialised when beta is 0 */
    }
}

int la_lu(int n, double *A, int *piv) {
    for (int k = 0; k < n; k++) {
        int p = k;
        double big = fabs(A[(size_t)k * n + k]);
        for (int i = k + 1; i < n; i++) {
            double v = fabs(A[(size_t)i * n + k]);
            if (v > big) { big = v; p = i; }
        }
        piv[k] = p;
        if (!(big > 0.0) || !isfinite(big)) return -1;
        if (p != k)
            for (int j = 0; j < n; j++) {
                double t = A[(size_t)k * n + j];
                A[(size_t)k * n + j] = A[(size_t)p * n + j];
                A[(size_t)p * n + j] = t;
            }
        const double inv = 1.0 / A[(size_t)k * n + k];
        for (int i = k + 1; i < n; i++) {
            double f = A[(size_t)i * n + k] *= inv;
            if (f == 0.0) continue;
            for (int j = k + 1; j < n; j++) A[(size_t)i * n + j] -= f * A[(size_t)k * n + j];
        }
    }
    return 0;
}

void la_lu_solve(int n, int m, const double *LU, const int *piv, double *B) {
    for (int k = 0; k < n; k++)
        if (piv[k] != k)
            for (int j = 0; j < m; j++) {
                double t = B[(size_t)k * m + j];
                B[(size_t)k * m + j] = B[(size_t)piv[k] * m + j];
                B[(size_t)piv[k] * m + j] = t;
            }
    for (int i = 0; i < n; i++)  /* L y = b, unit diagonal */
        for (int k = 0; k < i; k++) {
            const double f = LU[(size_t)i * n + k];
            if (f == 0.0) continue;
            for (int j = 0; j < m; j++) B[(size_t)i * m + j] -= f * B[(size_t)k * m + j];
        }
    for (int i = n - 1; i >= 0; i--) {  /* U x = y */
        for (int k = i + 1; k < n; k++) {
            const double f = LU[(size_t)i * n + k];
            if (f == 0.0) continue;
            for (int j = 0; j < m; j++) B[(size_t)i * m + j] -= f * B[(size_t)k * m + j];
        }
        const double inv = 1.0 / LU[(size_t)i * n + i];
        for (int j = 0; j < m; j++) B[(size_t)i * m + j] *= inv;
    }
}

/* Diagonal similarity D^-1 A D by powers of 2 that evens row and column norms (Parlett &
 * Reinsch, Numer. Math. 13 (1969) 293-304; LAPACK's gebal without permutation), in place;
 * d receives D. A mechanical state matrix (positions and velocities, stiffness up to
 * omega^2 ~ 1e7) is badly scaled; balanced, its exponential loses far less to squaring. */
static void balance(int n, double *A, double *d) {
    for (int i = 0; i < n; i++) d[i] = 1.0;
    for (int sweep = 0, changed = 1; changed && sweep < 100; sweep++) {
        changed = 0;
        for (int i = 0; i < n; i++) {
            double c = 0.0, r = 0.0;
            for (int j = 0; j < n; j++)
                if (j != i) {
                    c += fabs(A[(size_t)j * n + i]);
                    r += fabs(A[(size_t)i * n + j]);
                }
            if (c == 0.0 || r == 0.0) continue;
            const double s = c + r;
            double f = 1.0, g = r / 2.0;
            while (c < g) f *= 2.0, c *= 4.0;
            g = r * 2.0;
            while (c >= g) f /= 2.0, c /= 4.0;
            if ((c + r) / f < 0.95 * s) {
                changed = 1;
                d[i] *= f;
                for (int j = 0; j < n; j++) A[(size_t)i * n + j] /= f, A[(size_t)j * n + i] *= f;
            }
        }
    }
}

int la_expm(int n, const double *A, double *E, double *work, int *piv) {
    static const double b[14] = {64764752532480000.0, 32382376266240000.0, 7771770303897600.0,
                                 1187353796428800.0, 129060195264000.0, 10559470521600.0,
                                 670442572800.0, 33522128640.0, 1323241920.0, 40840800.0,
                                 960960.0, 16380.0, 182.0, 1.0};
    const double theta13 = 5.371920351148152;
    const size_t nn = (size_t)n * n;
    double *X = work, *A2 = work + nn, *A4 = work + 2 * nn, *A6 = work + 3 * nn;
    double *U = work + 4 * nn, *V = work + 5 * nn, *T = work + 6 * nn, *d = work + 7 * nn;
    for (size_t i = 0; i < nn; i++) {
        if (!isfinite(A[i])) return -1;
        X[i] = A[i];
    }
    balance(n, X, d);
    double norm = 0.0;
    for (int j = 0; j < n; j++) {
        double s = 0.0;
        for (int i = 0; i < n; i++) s += fabs(X[(size_t)i * n + j]);
        if (s > norm) norm = s;
    }
    if (!isfinite(norm)) return -1;
    int sq = 0;
    if (norm > theta13) sq = (int)ceil(log2(norm / theta13));
    const double scale = ldexp(1.0, -sq);
    for (size_t i = 0; i < nn; i++) X[i] *= scale;
    la_matmul(n, n, n, X, X, A2);
    la_matmul(n, n, n, A2, A2, A4);
    la_matmul(n, n, n, A4, A2, A6);
    /* U = X (A6 (b13 A6 + b11 A4 + b9 A2) + b7 A6 + b5 A4 + b3 A2 + b1 I) */
    for (size_t i = 0; i < nn; i++) T[i] = b[13] * A6[i] + b[11] * A4[i] + b[9] * A2[i];
    la_matmul(n, n, n, A6, T, U);
    for (size_t i = 0; i < nn; i++) U[i] += b[7] * A6[i] + b[5] * A4[i] + b[3] * A2[i];
    for (int i = 0; i < n; i++) U[(size_t)i * n + i] += b[1];
    la_matmul(n, n, n, X, U, T);
    memcpy(U, T, nn * sizeof(double));
    /* V = A6 (b12 A6 + b10 A4 + b8 A2) + b6 A6 + b4 A4 + b2 A2 + b0 I */
    for (size_t i = 0; i < nn; i++) T[i] = b[12] * A6[i] + b[10] * A4[i] + b[8] * A2[i];
    la_matmul(n, n, n, A6, T, V);
    for (size_t i = 0; i < nn; i++) V[i] += b[6] * A6[i] + b[4] * A4[i] + b[2] * A2[i];
    for (int i = 0; i < n; i++) V[(size_t)i * n + i] += b[0];
    /* (V - U) E = (V + U) */
    for (size_t i = 0; i < nn; i++) {
        T[i] = V[i] - U[i];
        E[i] = V[i] + U[i];
    }
    if (la_lu(n, T, piv) != 0) return -1;
    la_lu_solve(n, n, T, piv, E);
    for (int k = 0; k < sq; k++) {
        la_matmul(n, n, n, E, E, T);
        memcpy(E, T, nn * sizeof(double));
    }
    for (int i = 0; i < n; i++) /* undo the balancing: exp(A) = D exp(D^-1 A D) D^-1 */
        for (int j = 0; j < n; j++) E[(size_t)i * n + j] *= d[i] / d[j];
    return 0;
}
