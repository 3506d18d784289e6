/* A measured track profile for stand-alone running: the campaign format's track CSV,
 * columns `distance` [m] (strictly increasing) and `level` [m], '#' comment lines.
 * Between the points the level is the natural cubic spline through them, so level, slope
 * and curvature are continuous (a wheel's vertical acceleration stays finite). */
#ifndef RAILCAL_TRACK_H
#define RAILCAL_TRACK_H

#include <stddef.h>

typedef struct {
    int n;
    double *x;  /* [m] */
    double *z;  /* [m] */
    double *m;  /* second derivative of the spline at the points [1/m] */
    double min_spacing; /* [m] smallest distance between points */
} Track;

/* 0, or -1 with a message naming the file, line and problem. */
int track_load(Track *t, const char *path, char *msg, size_t msg_len);
void track_free(Track *t);
/* Level [m], slope [-], curvature [1/m] and its derivative [1/m^2] of the spline at s;
 * -1 outside the profile. *hint: the segment found last time for this caller (a wheel
 * moves on by a segment or so per call, so the search is usually one comparison). */
int track_eval(const Track *t, double s, double d[4], int *hint);

#endif
