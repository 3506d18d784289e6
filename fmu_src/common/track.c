#include "track.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static int column(const char *header, const char *name) {
    /* index of `name` in a comma-separated header, or -1 */
    int k = 0;
    const char *p = header;
    while (*p) {
        while (*p == ' ' || *p == '"') p++;
        size_t len = strlen(name);
        if (strncmp(p, name, len) == 0) {
            const char *q = p + len;
            while (*q == ' ' || *q == '"') q++;
            if (*q == ',' || *q == '\0' || *q == '\r' || *q == '\n') return k;
        }
        p = strchr(p, ',');
        if (!p) break;
        p++;
        k++;
    }
    return -1;
}

static int field(const char *line, int k, double *value) {
    const char *p = line;
    for (int i = 0; i < k; i++) {
        p = strchr(p, ',');
        if (!p) return -1;
        p++;
    }
    char *end;
    *value = strtod(p, &end);
    if (end == p) return -1;
    while (*end == ' ') end++;
    if (*end != ',' && *end != '\0' && *end != '\r' && *end != '\n') return -1;
    return isfinite(*value) ? 0 : -1;
}

int track_load(Track *t, const char *path, char *msg, size_t msg_len) {
    memset(t, 0, sizeof(*t));
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) {
        snprintf(msg, msg_len, "track profile %s: not a regular file", path);
        return -1;
    }
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(msg, msg_len, "track profile %s: cannot open", path);
        return -1;
    }
    char line[4096];
    int ix = -1, iz = -1, lineno = 0, cap = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *p = line;
        while (isspace((unsigned char)*p)) p++;
        if (*p == '#' || *p == '\0') continue;
        if (ix < 0) {
            ix = column(p, "distance");
            iz = column(p, "level");
            if (ix < 0 || iz < 0) {
                snprintf(msg, msg_len, "track profile %s line %d: the header needs columns distance and level",
                         path, lineno);
                goto fail;
            }
            continue;
        }
        double x, z;
        if (field(p, ix, &x) || field(p, iz, &z)) {
            snprintf(msg, msg_len, "track profile %s line %d: distance and level must be finite numbers", path,
                     lineno);
            goto fail;
        }
        if (t->n && !(x > t->x[t->n - 1])) {
            snprintf(msg, msg_len, "track profile %s line %d: distance %g m is not above the previous %g m", path,
                     lineno, x, t->x[t->n - 1]);
            goto fail;
        }
        if (t->n == cap) {
            cap = cap ? 2 * cap : 1024;
            double *nx = realloc(t->x, cap * sizeof(double)), *nz;
            if (!nx) goto oom;
            t->x = nx;
            nz = realloc(t->z, cap * sizeof(double));
            if (!nz) goto oom;
            t->z = nz;
        }
        t->x[t->n] = x;
        t->z[t->n] = z;
        t->n++;
    }
    fclose(f);
    if (t->n < 2) {
        snprintf(msg, msg_len, "track profile %s: needs at least two points, has %d", path, t->n);
        track_free(t);
        return -1;
    }
    /* natural cubic spline: tridiagonal system for the second derivatives (Thomas) */
    t->m = calloc(t->n, sizeof(double));
    double *cp = calloc(t->n, sizeof(double));
    if (!t->m || !cp) {
        free(cp);
        snprintf(msg, msg_len, "track profile %s: out of memory", path);
        track_free(t);
        return -1;
    }
    for (int i = 1; i < t->n - 1; i++) {
        const double h0 = t->x[i] - t->x[i - 1], h1 = t->x[i + 1] - t->x[i];
        const double a = h0 / 6, b = (h0 + h1) / 3, c = h1 / 6;
        const double r = (t->z[i + 1] - t->z[i]) / h1 - (t->z[i] - t->z[i - 1]) / h0;
        const double den = b - a * cp[i - 1];
        cp[i] = c / den;
        t->m[i] = (r - a * t->m[i - 1]) / den;
    }
    for (int i = t->n - 2; i >= 1; i--) t->m[i] -= cp[i] * t->m[i + 1];
    free(cp);
    t->min_spacing = INFINITY;
    for (int i = 1; i < t->n; i++)
        if (t->x[i] - t->x[i - 1] < t->min_spacing) t->min_spacing = t->x[i] - t->x[i - 1];
    return 0;
oom:
    snprintf(msg, msg_len, "track profile %s: out of memory at line %d", path, lineno);
fail:
    fclose(f);
    track_free(t);
    return -1;
}

void track_free(Track *t) {
    free(t->x);
    free(t->z);
    free(t->m);
    memset(t, 0, sizeof(*t));
}

int track_eval(const Track *t, double s, double d[4], int *hint) {
    if (t->n < 2 || !(s >= t->x[0]) || !(s <= t->x[t->n - 1])) return -1;
    int lo = hint ? *hint : 0, hi;
    if (lo < 0 || lo > t->n - 2) lo = 0;
    for (int walk = 0; walk < 4 && lo < t->n - 2 && t->x[lo + 1] <= s; walk++) lo++;
    for (int walk = 0; walk < 4 && lo > 0 && t->x[lo] > s; walk++) lo--;
    if (t->x[lo] <= s && s <= t->x[lo + 1]) {
        hi = lo + 1;
    } else {
        lo = 0, hi = t->n - 1;
        while (hi - lo > 1) {
            int mid = (lo + hi) / 2;
            if (t->x[mid] <= s) lo = mid; else hi = mid;
        }
    }
    if (hint) *hint = lo;
    const double h = t->x[hi] - t->x[lo], a = (t->x[hi] - s) / h, b = (s - t->x[lo]) / h;
    const double m0 = t->m[lo], m1 = t->m[hi];
    d[0] = a * t->z[lo] + b * t->z[hi] + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6;
    d[1] = (t->z[hi] - t->z[lo]) / h - (3 * a * a - 1) * h / 6 * m0 + (3 * b * b - 1) * h / 6 * m1;
    d[2] = a * m0 + b * m1;
    d[3] = (m1 - m0) / h;
    return 0;
}
