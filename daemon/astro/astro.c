/* astro.c - sun (NREL SPA) and moon (Meeus ch. 47/48) for a time and a place. */
#include "astro.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#include "simclock.h"

#define DEG (M_PI / 180.0)
#define JD_UNIX_EPOCH 2440587.5
#define JD_J2000 2451545.0
#define AU_KM 149597870.7
#define EARTH_EQUATORIAL_RADIUS_KM 6378.14	/* the value SPA and Meeus ch. 40 use */
#define MOON_RADIUS_KM 1737.4
#define MOON_MEAN_DISTANCE_KM 384400.0
#define SUN_RADIUS_1AU_DEG (959.63 / 3600.0)
#define SUN_RADIUS_SPA_DEG 0.26667		/* SPA's fixed sun radius for rise/set */

/* ------------------------------------------------------------------------ */
/* SPA report, table A4.2: earth periodic terms (A, B, C) of A cos(B + C JME),
 * in 1e-8 rad for L and B and 1e-8 AU for R. */

struct term {
	double a, b, c;
};

static const struct term L0[] = {
	{ 175347046, 0, 0 }, { 3341656, 4.6692568, 6283.07585 }, { 34894, 4.6261, 12566.1517 },
	{ 3497, 2.7441, 5753.3849 }, { 3418, 2.8289, 3.5231 }, { 3136, 3.6277, 77713.7715 },
	{ 2676, 4.4181, 7860.4194 }, { 2343, 6.1352, 3930.2097 }, { 1324, 0.7425, 11506.7698 },
	{ 1273, 2.0371, 529.691 }, { 1199, 1.1096, 1577.3435 }, { 990, 5.233, 5884.927 },
	{ 902, 2.045, 26.298 }, { 857, 3.508, 398.149 }, { 780, 1.179, 5223.694 },
	{ 753, 2.533, 5507.553 }, { 505, 4.583, 18849.228 }, { 492, 4.205, 775.523 },
	{ 357, 2.92, 0.067 }, { 317, 5.849, 11790.629 }, { 284, 1.899, 796.298 },
	{ 271, 0.315, 10977.079 }, { 243, 0.345, 5486.778 }, { 206, 4.806, 2544.314 },
	{ 205, 1.869, 5573.143 }, { 202, 2.458, 6069.777 }, { 156, 0.833, 213.299 },
	{ 132, 3.411, 2942.463 }, { 126, 1.083, 20.775 }, { 115, 0.645, 0.98 },
	{ 103, 0.636, 4694.003 }, { 102, 0.976, 15720.839 }, { 102, 4.267, 7.114 },
	{ 99, 6.21, 2146.17 }, { 98, 0.68, 155.42 }, { 86, 5.98, 161000.69 },
	{ 85, 1.3, 6275.96 }, { 85, 3.67, 71430.7 }, { 80, 1.81, 17260.15 },
	{ 79, 3.04, 12036.46 }, { 75, 1.76, 5088.63 }, { 74, 3.5, 3154.69 },
	{ 74, 4.68, 801.82 }, { 70, 0.83, 9437.76 }, { 62, 3.98, 8827.39 },
	{ 61, 1.82, 7084.9 }, { 57, 2.78, 6286.6 }, { 56, 4.39, 14143.5 },
	{ 56, 3.47, 6279.55 }, { 52, 0.19, 12139.55 }, { 52, 1.33, 1748.02 },
	{ 51, 0.28, 5856.48 }, { 49, 0.49, 1194.45 }, { 41, 5.37, 8429.24 },
	{ 41, 2.4, 19651.05 }, { 39, 6.17, 10447.39 }, { 37, 6.04, 10213.29 },
	{ 37, 2.57, 1059.38 }, { 36, 1.71, 2352.87 }, { 36, 1.78, 6812.77 },
	{ 33, 0.59, 17789.85 }, { 30, 0.44, 83996.85 }, { 30, 2.74, 1349.87 },
	{ 25, 3.16, 4690.48 },
};
static const struct term L1[] = {
	{ 628331966747, 0, 0 }, { 206059, 2.678235, 6283.07585 }, { 4303, 2.6351, 12566.1517 },
	{ 425, 1.59, 3.523 }, { 119, 5.796, 26.298 }, { 109, 2.966, 1577.344 },
	{ 93, 2.59, 18849.23 }, { 72, 1.14, 529.69 }, { 68, 1.87, 398.15 },
	{ 67, 4.41, 5507.55 }, { 59, 2.89, 5223.69 }, { 56, 2.17, 155.42 },
	{ 45, 0.4, 796.3 }, { 36, 0.47, 775.52 }, { 29, 2.65, 7.11 },
	{ 21, 5.34, 0.98 }, { 19, 1.85, 5486.78 }, { 19, 4.97, 213.3 },
	{ 17, 2.99, 6275.96 }, { 16, 0.03, 2544.31 }, { 16, 1.43, 2146.17 },
	{ 15, 1.21, 10977.08 }, { 12, 2.83, 1748.02 }, { 12, 3.26, 5088.63 },
	{ 12, 5.27, 1194.45 }, { 12, 2.08, 4694 }, { 11, 0.77, 553.57 },
	{ 10, 1.3, 6286.6 }, { 10, 4.24, 1349.87 }, { 9, 2.7, 242.73 },
	{ 9, 5.64, 951.72 }, { 8, 5.3, 2352.87 }, { 6, 2.65, 9437.76 },
	{ 6, 4.67, 4690.48 },
};
static const struct term L2[] = {
	{ 52919, 0, 0 }, { 8720, 1.0721, 6283.0758 }, { 309, 0.867, 12566.152 },
	{ 27, 0.05, 3.52 }, { 16, 5.19, 26.3 }, { 16, 3.68, 155.42 },
	{ 10, 0.76, 18849.23 }, { 9, 2.06, 77713.77 }, { 7, 0.83, 775.52 },
	{ 5, 4.66, 1577.34 }, { 4, 1.03, 7.11 }, { 4, 3.44, 5573.14 },
	{ 3, 5.14, 796.3 }, { 3, 6.05, 5507.55 }, { 3, 1.19, 242.73 },
	{ 3, 6.12, 529.69 }, { 3, 0.31, 398.15 }, { 3, 2.28, 553.57 },
	{ 2, 4.38, 5223.69 }, { 2, 3.75, 0.98 },
};
static const struct term L3[] = {
	{ 289, 5.844, 6283.076 }, { 35, 0, 0 }, { 17, 5.49, 12566.15 },
	{ 3, 5.2, 155.42 }, { 1, 4.72, 3.52 }, { 1, 5.3, 18849.23 },
	{ 1, 5.97, 242.73 },
};
static const struct term L4[] = {
	{ 114, 3.142, 0 }, { 8, 4.13, 6283.08 }, { 1, 3.84, 12566.15 },
};
static const struct term L5[] = {
	{ 1, 3.14, 0 },
};
static const struct term B0[] = {
	{ 280, 3.199, 84334.662 }, { 102, 5.422, 5507.553 }, { 80, 3.88, 5223.69 },
	{ 44, 3.7, 2352.87 }, { 32, 4, 1577.34 },
};
static const struct term B1[] = {
	{ 9, 3.9, 5507.55 }, { 6, 1.73, 5223.69 },
};
static const struct term R0[] = {
	{ 100013989, 0, 0 }, { 1670700, 3.0984635, 6283.07585 }, { 13956, 3.05525, 12566.1517 },
	{ 3084, 5.1985, 77713.7715 }, { 1628, 1.1739, 5753.3849 }, { 1576, 2.8469, 7860.4194 },
	{ 925, 5.453, 11506.77 }, { 542, 4.564, 3930.21 }, { 472, 3.661, 5884.927 },
	{ 346, 0.964, 5507.553 }, { 329, 5.9, 5223.694 }, { 307, 0.299, 5573.143 },
	{ 243, 4.273, 11790.629 }, { 212, 5.847, 1577.344 }, { 186, 5.022, 10977.079 },
	{ 175, 3.012, 18849.228 }, { 110, 5.055, 5486.778 }, { 98, 0.89, 6069.78 },
	{ 86, 5.69, 15720.84 }, { 86, 1.27, 161000.69 }, { 65, 0.27, 17260.15 },
	{ 63, 0.92, 529.69 }, { 57, 2.01, 83996.85 }, { 56, 5.24, 71430.7 },
	{ 49, 3.25, 2544.31 }, { 47, 2.58, 775.52 }, { 45, 5.54, 9437.76 },
	{ 43, 6.01, 6275.96 }, { 39, 5.36, 4694 }, { 38, 2.39, 8827.39 },
	{ 37, 0.83, 19651.05 }, { 37, 4.9, 12139.55 }, { 36, 1.67, 12036.46 },
	{ 35, 1.84, 2942.46 }, { 33, 0.24, 7084.9 }, { 32, 0.18, 5088.63 },
	{ 32, 1.78, 398.15 }, { 28, 1.21, 6286.6 }, { 28, 1.9, 6279.55 },
	{ 26, 4.59, 10447.39 },
};
static const struct term R1[] = {
	{ 103019, 1.10749, 6283.07585 }, { 1721, 1.0644, 12566.1517 }, { 702, 3.142, 0 },
	{ 32, 1.02, 18849.23 }, { 31, 2.84, 5507.55 }, { 25, 1.32, 5223.69 },
	{ 18, 1.42, 1577.34 }, { 10, 5.91, 10977.08 }, { 9, 1.42, 6275.96 },
	{ 9, 0.27, 5486.78 },
};
static const struct term R2[] = {
	{ 4359, 5.7846, 6283.0758 }, { 124, 5.579, 12566.152 }, { 12, 3.14, 0 },
	{ 9, 3.63, 77713.77 }, { 6, 1.87, 5573.14 }, { 3, 5.47, 18849.23 },
};
static const struct term R3[] = {
	{ 145, 4.273, 6283.076 }, { 7, 3.92, 12566.15 },
};
static const struct term R4[] = {
	{ 4, 2.56, 6283.08 },
};

#define N(a) (sizeof(a) / sizeof((a)[0]))

struct series {
	const struct term *t;
	size_t n;
};
static const struct series L_series[] = {
	{ L0, N(L0) }, { L1, N(L1) }, { L2, N(L2) }, { L3, N(L3) }, { L4, N(L4) }, { L5, N(L5) },
};
static const struct series B_series[] = { { B0, N(B0) }, { B1, N(B1) } };
static const struct series R_series[] = {
	{ R0, N(R0) }, { R1, N(R1) }, { R2, N(R2) }, { R3, N(R3) }, { R4, N(R4) },
};

/* SPA table A4.3: nutation in longitude and obliquity. Multiples of the
 * arguments D, M, M', F, Omega, then a, b (psi) and c, d (epsilon) in
 * 0.0001 arcsec: (a + b JCE) sin(arg), (c + d JCE) cos(arg). */
struct nut_term {
	signed char y[5];
	double a, b, c, d;
};

static const struct nut_term nutation_terms[] = {
	{ { 0, 0, 0, 0, 1 }, -171996, -174.2, 92025, 8.9 },
	{ { -2, 0, 0, 2, 2 }, -13187, -1.6, 5736, -3.1 },
	{ { 0, 0, 0, 2, 2 }, -2274, -0.2, 977, -0.5 },
	{ { 0, 0, 0, 0, 2 }, 2062, 0.2, -895, 0.5 },
	{ { 0, 1, 0, 0, 0 }, 1426, -3.4, 54, -0.1 },
	{ { 0, 0, 1, 0, 0 }, 712, 0.1, -7, 0 },
	{ { -2, 1, 0, 2, 2 }, -517, 1.2, 224, -0.6 },
	{ { 0, 0, 0, 2, 1 }, -386, -0.4, 200, 0 },
	{ { 0, 0, 1, 2, 2 }, -301, 0, 129, -0.1 },
	{ { -2, -1, 0, 2, 2 }, 217, -0.5, -95, 0.3 },
	{ { -2, 0, 1, 0, 0 }, -158, 0, 0, 0 },
	{ { -2, 0, 0, 2, 1 }, 129, 0.1, -70, 0 },
	{ { 0, 0, -1, 2, 2 }, 123, 0, -53, 0 },
	{ { 2, 0, 0, 0, 0 }, 63, 0, 0, 0 },
	{ { 0, 0, 1, 0, 1 }, 63, 0.1, -33, 0 },
	{ { 2, 0, -1, 2, 2 }, -59, 0, 26, 0 },
	{ { 0, 0, -1, 0, 1 }, -58, -0.1, 32, 0 },
	{ { 0, 0, 1, 2, 1 }, -51, 0, 27, 0 },
	{ { -2, 0, 2, 0, 0 }, 48, 0, 0, 0 },
	{ { 0, 0, -2, 2, 1 }, 46, 0, -24, 0 },
	{ { 2, 0, 0, 2, 2 }, -38, 0, 16, 0 },
	{ { 0, 0, 2, 2, 2 }, -31, 0, 13, 0 },
	{ { 0, 0, 2, 0, 0 }, 29, 0, 0, 0 },
	{ { -2, 0, 1, 2, 2 }, 29, 0, -12, 0 },
	{ { 0, 0, 0, 2, 0 }, 26, 0, 0, 0 },
	{ { -2, 0, 0, 2, 0 }, -22, 0, 0, 0 },
	{ { 0, 0, -1, 2, 1 }, 21, 0, -10, 0 },
	{ { 0, 2, 0, 0, 0 }, 17, -0.1, 0, 0 },
	{ { 2, 0, -1, 0, 1 }, 16, 0, -8, 0 },
	{ { -2, 2, 0, 2, 2 }, -16, 0.1, 7, 0 },
	{ { 0, 1, 0, 0, 1 }, -15, 0, 9, 0 },
	{ { -2, 0, 1, 0, 1 }, -13, 0, 7, 0 },
	{ { 0, -1, 0, 0, 1 }, -12, 0, 6, 0 },
	{ { 0, 0, 2, -2, 0 }, 11, 0, 0, 0 },
	{ { 2, 0, -1, 2, 1 }, -10, 0, 5, 0 },
	{ { 2, 0, 1, 2, 2 }, -8, 0, 3, 0 },
	{ { 0, 1, 0, 2, 2 }, 7, 0, -3, 0 },
	{ { -2, 1, 1, 0, 0 }, -7, 0, 0, 0 },
	{ { 0, -1, 0, 2, 2 }, -7, 0, 3, 0 },
	{ { 2, 0, 0, 2, 1 }, -7, 0, 3, 0 },
	{ { 2, 0, 1, 0, 0 }, 6, 0, 0, 0 },
	{ { -2, 0, 2, 2, 2 }, 6, 0, -3, 0 },
	{ { -2, 0, 1, 2, 1 }, 6, 0, -3, 0 },
	{ { 2, 0, -2, 0, 1 }, -6, 0, 3, 0 },
	{ { 2, 0, 0, 0, 1 }, -6, 0, 3, 0 },
	{ { 0, -1, 1, 0, 0 }, 5, 0, 0, 0 },
	{ { -2, -1, 0, 2, 1 }, -5, 0, 3, 0 },
	{ { -2, 0, 0, 0, 1 }, -5, 0, 3, 0 },
	{ { 0, 0, 2, 2, 1 }, -5, 0, 3, 0 },
	{ { -2, 0, 2, 0, 1 }, 4, 0, 0, 0 },
	{ { -2, 1, 0, 2, 1 }, 4, 0, 0, 0 },
	{ { 0, 0, 1, -2, 0 }, 4, 0, 0, 0 },
	{ { -1, 0, 1, 0, 0 }, -4, 0, 0, 0 },
	{ { -2, 1, 0, 0, 0 }, -4, 0, 0, 0 },
	{ { 1, 0, 0, 0, 0 }, -4, 0, 0, 0 },
	{ { 0, 0, 1, 2, 0 }, 3, 0, 0, 0 },
	{ { 0, 0, -2, 2, 2 }, -3, 0, 0, 0 },
	{ { -1, -1, 1, 0, 0 }, -3, 0, 0, 0 },
	{ { 0, 1, 1, 0, 0 }, -3, 0, 0, 0 },
	{ { 0, -1, 1, 2, 2 }, -3, 0, 0, 0 },
	{ { 2, -1, -1, 2, 2 }, -3, 0, 0, 0 },
	{ { 0, 0, 3, 2, 2 }, -3, 0, 0, 0 },
	{ { 2, -1, 0, 2, 2 }, -3, 0, 0, 0 },
};

/* Meeus table 47.A: multiples of D, M, M', F; then the longitude term
 * (1e-6 deg, sine) and the distance term (1e-3 km, cosine). */
struct moon_lr_term {
	signed char d, m, mp, f;
	double l, r;
};

static const struct moon_lr_term moon_lr[] = {
	{ 0, 0, 1, 0, 6288774, -20905355 }, { 2, 0, -1, 0, 1274027, -3699111 },
	{ 2, 0, 0, 0, 658314, -2955968 }, { 0, 0, 2, 0, 213618, -569925 },
	{ 0, 1, 0, 0, -185116, 48888 }, { 0, 0, 0, 2, -114332, -3149 },
	{ 2, 0, -2, 0, 58793, 246158 }, { 2, -1, -1, 0, 57066, -152138 },
	{ 2, 0, 1, 0, 53322, -170733 }, { 2, -1, 0, 0, 45758, -204586 },
	{ 0, 1, -1, 0, -40923, -129620 }, { 1, 0, 0, 0, -34720, 108743 },
	{ 0, 1, 1, 0, -30383, 104755 }, { 2, 0, 0, -2, 15327, 10321 },
	{ 0, 0, 1, 2, -12528, 0 }, { 0, 0, 1, -2, 10980, 79661 },
	{ 4, 0, -1, 0, 10675, -34782 }, { 0, 0, 3, 0, 10034, -23210 },
	{ 4, 0, -2, 0, 8548, -21636 }, { 2, 1, -1, 0, -7888, 24208 },
	{ 2, 1, 0, 0, -6766, 30824 }, { 1, 0, -1, 0, -5163, -8379 },
	{ 1, 1, 0, 0, 4987, -16675 }, { 2, -1, 1, 0, 4036, -12831 },
	{ 2, 0, 2, 0, 3994, -10445 }, { 4, 0, 0, 0, 3861, -11650 },
	{ 2, 0, -3, 0, 3665, 14403 }, { 0, 1, -2, 0, -2689, -7003 },
	{ 2, 0, -1, 2, -2602, 0 }, { 2, -1, -2, 0, 2390, 10056 },
	{ 1, 0, 1, 0, -2348, 6322 }, { 2, -2, 0, 0, 2236, -9884 },
	{ 0, 1, 2, 0, -2120, 5751 }, { 0, 2, 0, 0, -2069, 0 },
	{ 2, -2, -1, 0, 2048, -4950 }, { 2, 0, 1, -2, -1773, 4130 },
	{ 2, 0, 0, 2, -1595, 0 }, { 4, -1, -1, 0, 1215, -3958 },
	{ 0, 0, 2, 2, -1110, 0 }, { 3, 0, -1, 0, -892, 3258 },
	{ 2, 1, 1, 0, -810, 2616 }, { 4, -1, -2, 0, 759, -1897 },
	{ 0, 2, -1, 0, -713, -2117 }, { 2, 2, -1, 0, -700, 2354 },
	{ 2, 1, -2, 0, 691, 0 }, { 2, -1, 0, -2, 596, 0 },
	{ 4, 0, 1, 0, 549, -1423 }, { 0, 0, 4, 0, 537, -1117 },
	{ 4, -1, 0, 0, 520, -1571 }, { 1, 0, -2, 0, -487, -1739 },
	{ 2, 1, 0, -2, -399, 0 }, { 0, 0, 2, -2, -381, -4421 },
	{ 1, 1, 1, 0, 351, 0 }, { 3, 0, -2, 0, -340, 0 },
	{ 4, 0, -3, 0, 330, 0 }, { 2, -1, 2, 0, 327, 0 },
	{ 0, 2, 1, 0, -323, 1165 }, { 1, 1, -1, 0, 299, 0 },
	{ 2, 0, 3, 0, 294, 0 }, { 2, 0, -1, -2, 0, 8752 },
};

/* Meeus table 47.B: multiples of D, M, M', F; latitude term (1e-6 deg, sine). */
struct moon_b_term {
	signed char d, m, mp, f;
	double b;
};

static const struct moon_b_term moon_b[] = {
	{ 0, 0, 0, 1, 5128122 }, { 0, 0, 1, 1, 280602 }, { 0, 0, 1, -1, 277693 },
	{ 2, 0, 0, -1, 173237 }, { 2, 0, -1, 1, 55413 }, { 2, 0, -1, -1, 46271 },
	{ 2, 0, 0, 1, 32573 }, { 0, 0, 2, 1, 17198 }, { 2, 0, 1, -1, 9266 },
	{ 0, 0, 2, -1, 8822 }, { 2, -1, 0, -1, 8216 }, { 2, 0, -2, -1, 4324 },
	{ 2, 0, 1, 1, 4200 }, { 2, 1, 0, -1, -3359 }, { 2, -1, -1, 1, 2463 },
	{ 2, -1, 0, 1, 2211 }, { 2, -1, -1, -1, 2065 }, { 0, 1, -1, -1, -1870 },
	{ 4, 0, -1, -1, 1828 }, { 0, 1, 0, 1, -1794 }, { 0, 0, 0, 3, -1749 },
	{ 0, 1, -1, 1, -1565 }, { 1, 0, 0, 1, -1491 }, { 0, 1, 1, 1, -1475 },
	{ 0, 1, 1, -1, -1410 }, { 0, 1, 0, -1, -1344 }, { 1, 0, 0, -1, -1335 },
	{ 0, 0, 3, 1, 1107 }, { 4, 0, 0, -1, 1021 }, { 4, 0, -1, 1, 833 },
	{ 0, 0, 1, -3, 777 }, { 4, 0, -2, 1, 671 }, { 2, 0, 0, -3, 607 },
	{ 2, 0, 2, -1, 596 }, { 2, -1, 1, -1, 491 }, { 2, 0, -2, 1, -451 },
	{ 0, 0, 3, -1, 439 }, { 2, 0, 2, 1, 422 }, { 2, 0, -3, -1, 421 },
	{ 2, 1, -1, 1, -366 }, { 2, 1, 0, 1, -351 }, { 4, 0, 0, 1, 331 },
	{ 2, -1, 1, 1, 315 }, { 2, -2, 0, -1, 302 }, { 0, 0, 1, 3, -283 },
	{ 2, 1, 1, -1, -229 }, { 1, 1, 0, -1, 223 }, { 1, 1, 0, 1, 223 },
	{ 0, 1, -2, -1, -220 }, { 2, 1, -1, -1, -220 }, { 1, 0, 1, 1, -185 },
	{ 2, -1, -2, -1, 181 }, { 0, 1, 2, 1, -177 }, { 4, 0, -2, -1, 176 },
	{ 4, -1, -1, -1, 166 }, { 1, 0, 1, -1, -164 }, { 4, 0, 1, -1, 132 },
	{ 1, 0, -1, -1, -119 }, { 4, -1, 0, -1, 115 }, { 2, -2, 0, 1, 107 },
};

/* ------------------------------------------------------------------------ */

static double wrap360(double x)
{
	x = fmod(x, 360.0);
	return x < 0.0 ? x + 360.0 : x;
}

static double wrap180(double x)
{
	x = wrap360(x + 180.0);
	return x - 180.0;
}

static double wrap01(double x)
{
	return x - floor(x);
}

static double sind(double x) { return sin(x * DEG); }
static double cosd(double x) { return cos(x * DEG); }
static double tand(double x) { return tan(x * DEG); }
static double asind(double x) { return asin(fmin(1.0, fmax(-1.0, x))) / DEG; }
static double atan2d(double y, double x) { return atan2(y, x) / DEG; }

/* sum_i (sum_j A cos(B + C t)) t^i, the SPA/VSOP87 polynomial of series. */
static double earth_series(const struct series *s, size_t n, double jme)
{
	double sum = 0.0, tp = 1.0;

	for (size_t i = 0; i < n; i++) {
		double part = 0.0;
		for (size_t j = 0; j < s[i].n; j++)
			part += s[i].t[j].a * cos(s[i].t[j].b + s[i].t[j].c * jme);
		sum += part * tp;
		tp *= jme;
	}
	return sum / 1e8;
}

/* Nutation in longitude and obliquity (degrees) at JCE, SPA 3.4. */
static void nutation(double jce, double *ret_dpsi_deg, double *ret_deps_deg)
{
	double x[5], dpsi = 0.0, deps = 0.0;
	double t2 = jce * jce, t3 = t2 * jce;

	x[0] = 297.85036 + 445267.111480 * jce - 0.0019142 * t2 + t3 / 189474.0;
	x[1] = 357.52772 + 35999.050340 * jce - 0.0001603 * t2 - t3 / 300000.0;
	x[2] = 134.96298 + 477198.867398 * jce + 0.0086972 * t2 + t3 / 56250.0;
	x[3] = 93.27191 + 483202.017538 * jce - 0.0036825 * t2 + t3 / 327270.0;
	x[4] = 125.04452 - 1934.136261 * jce + 0.0020708 * t2 + t3 / 450000.0;
	for (size_t i = 0; i < N(nutation_terms); i++) {
		const struct nut_term *n = &nutation_terms[i];
		double arg = 0.0;
		for (int j = 0; j < 5; j++)
			arg += x[j] * n->y[j];
		arg *= DEG;
		dpsi += (n->a + n->b * jce) * sin(arg);
		deps += (n->c + n->d * jce) * cos(arg);
	}
	*ret_dpsi_deg = dpsi / 36000000.0;
	*ret_deps_deg = deps / 36000000.0;
}

/* True obliquity of the ecliptic (degrees), SPA 3.5. */
static double obliquity_deg(double jme, double deps_deg)
{
	double u = jme / 10.0;
	static const double c[] = { 84381.448, -4680.93, -1.55, 1999.25, -51.38, -249.67,
				    -39.05, 7.12, 27.87, 5.79, 2.45 };
	double e0 = 0.0, up = 1.0;

	for (size_t i = 0; i < N(c); i++, up *= u)
		e0 += c[i] * up;
	return e0 / 3600.0 + deps_deg;
}

/* Everything geocentric about the sun at one instant. */
struct geo {
	double jd, jc, jce, jme;
	double r_au;
	double dpsi_deg, eps_deg;
	double lambda_deg;	/* apparent ecliptic longitude */
	double alpha_deg;	/* apparent right ascension, [0, 360) */
	double delta_deg;	/* apparent declination */
	double nu_deg;		/* apparent sidereal time at Greenwich, [0, 360) */
};

/* Time arguments and the earth-dependent parts; jd is UT1. */
static void geo_time(double jd, double delta_t_s, struct geo *g)
{
	g->jd = jd;
	g->jc = (jd - JD_J2000) / 36525.0;
	g->jce = (jd + delta_t_s / 86400.0 - JD_J2000) / 36525.0;
	g->jme = g->jce / 10.0;
	nutation(g->jce, &g->dpsi_deg, &g->eps_deg);
	g->eps_deg = obliquity_deg(g->jme, g->eps_deg);
	double nu0 = 280.46061837 + 360.98564736629 * (jd - JD_J2000) +
		     0.000387933 * g->jc * g->jc - g->jc * g->jc * g->jc / 38710000.0;
	g->nu_deg = wrap360(wrap360(nu0) + g->dpsi_deg * cosd(g->eps_deg));
}

/* Apparent equatorial coordinates from apparent ecliptic ones, SPA 3.8-3.9. */
static void ecliptic_to_equatorial(double lambda_deg, double beta_deg, double eps_deg,
				   double *ret_alpha_deg, double *ret_delta_deg)
{
	double sl = sind(lambda_deg), ce = cosd(eps_deg), se = sind(eps_deg);

	*ret_alpha_deg = wrap360(atan2d(sl * ce - tand(beta_deg) * se, cosd(lambda_deg)));
	*ret_delta_deg = asind(sind(beta_deg) * ce + cosd(beta_deg) * se * sl);
}

/* SPA 3.1-3.9 for the sun. */
static void sun_geocentric(double jd, double delta_t_s, struct geo *g)
{
	geo_time(jd, delta_t_s, g);
	double l_deg = wrap360(earth_series(L_series, N(L_series), g->jme) / DEG);
	double b_deg = earth_series(B_series, N(B_series), g->jme) / DEG;
	g->r_au = earth_series(R_series, N(R_series), g->jme);
	double theta_deg = wrap360(l_deg + 180.0);
	double beta_deg = -b_deg;
	double aberration_deg = -20.4898 / (3600.0 * g->r_au);
	g->lambda_deg = theta_deg + g->dpsi_deg + aberration_deg;
	ecliptic_to_equatorial(g->lambda_deg, beta_deg, g->eps_deg, &g->alpha_deg, &g->delta_deg);
}

/* Refraction (degrees) at the true elevation e0_deg, SPA eq. 42:
 * Saemundsson's formula scaled by pressure and temperature. Applied only
 * while the body is not below the horizon by more than its radius plus the
 * horizon refraction, where the formula stops meaning anything. */
static double refraction_deg(double e0_deg, double radius_deg, const struct astro_options *o)
{
	if (e0_deg < -(radius_deg + o->horizon_refraction_deg))
		return 0.0;
	return o->pressure_mbar / 1010.0 * 283.0 / (273.0 + o->temperature_c) * 1.02 /
	       (60.0 * tand(e0_deg + 10.3 / (e0_deg + 5.11)));
}

static void set_direction(struct astro_direction *d, double elevation_deg, double azimuth_deg)
{
	d->elevation_deg = elevation_deg;
	d->zenith_deg = 90.0 - elevation_deg;
	d->azimuth_deg = azimuth_deg;
}

/* The observer's distance from the earth's axis (x) and from the equator's
 * plane (y), in equatorial radii, on SPA's ellipsoid (SPA 3.12.2-3.12.5). */
static void observer_xy(const struct astro_site *site, double *ret_x, double *ret_y)
{
	double phi = site->lat_deg;
	double u = atan(0.99664719 * tand(phi));
	double e_rel = site->elevation_m / (EARTH_EQUATORIAL_RADIUS_KM * 1000.0);

	*ret_x = cos(u) + e_rel * cosd(phi);
	*ret_y = 0.99664719 * sin(u) + e_rel * sind(phi);
}

/* From geocentric apparent (alpha, delta) to the topocentric horizon, SPA
 * 3.10-3.15 (Meeus ch. 40 in SPA's notation). sin_parallax is the sine of
 * the equatorial horizontal parallax. ret_h_deg gets the topocentric hour
 * angle. */
static void topocentric(const struct astro_site *site, const struct astro_options *o,
			double alpha_deg, double delta_deg, double nu_deg, double sin_parallax,
			double radius_deg, struct astro_direction *ret_geometric,
			struct astro_direction *ret_apparent, double *ret_h_deg)
{
	double phi = site->lat_deg, x, y;
	double h_deg = wrap360(nu_deg + site->lon_deg - alpha_deg);
	observer_xy(site, &x, &y);
	double cd = cosd(delta_deg), ch = cosd(h_deg);
	double den = cd - x * sin_parallax * ch;
	double dalpha_deg = atan2d(-x * sin_parallax * sind(h_deg), den);
	double delta_p_deg = atan2d((sind(delta_deg) - y * sin_parallax) * cosd(dalpha_deg), den);
	double hp_deg = h_deg - dalpha_deg;

	double e0_deg = asind(sind(phi) * sind(delta_p_deg) + cosd(phi) * cosd(delta_p_deg) * cosd(hp_deg));
	double gamma_deg = atan2d(sind(hp_deg), cosd(hp_deg) * sind(phi) - tand(delta_p_deg) * cosd(phi));
	double azimuth_deg = wrap360(gamma_deg + 180.0);

	set_direction(ret_geometric, e0_deg, azimuth_deg);
	set_direction(ret_apparent, e0_deg + refraction_deg(e0_deg, radius_deg, o), azimuth_deg);
	if (ret_h_deg)
		*ret_h_deg = wrap180(hp_deg);
}

/* ------------------------------------------------------------------------ */

void astro_options_default(struct astro_options *ret)
{
	*ret = (struct astro_options){
		.delta_t_auto = true,
		.delta_t_s = 0.0,
		.delta_ut1_s = 0.0,
		.pressure_mbar = 1013.25,
		.temperature_c = 15.0,
		.horizon_refraction_deg = 0.5667,
	};
}

static int refuse(char *err, size_t err_size, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static int refuse(char *err, size_t err_size, const char *fmt, ...)
{
	va_list ap;

	if (err && err_size) {
		va_start(ap, fmt);
		vsnprintf(err, err_size, fmt, ap);
		va_end(ap);
	}
	return -EINVAL;
}

/* A finite number in [lo, hi]. NaN fails every comparison, hence the form. */
static bool in_range(double v, double lo, double hi)
{
	return v >= lo && v <= hi;
}

static int check_site(const struct astro_site *s, char *err, size_t err_size)
{
	if (!s)
		return refuse(err, err_size, "site: missing");
	if (!in_range(s->lat_deg, -90.0, 90.0))
		return refuse(err, err_size, "lat_deg: %g is not in [-90, 90]", s->lat_deg);
	if (!in_range(s->lon_deg, -180.0, 180.0))
		return refuse(err, err_size, "lon_deg: %g is not in [-180, 180]", s->lon_deg);
	if (!in_range(s->elevation_m, -1000.0, 1e5))
		return refuse(err, err_size, "elevation_m: %g is not in [-1000, 100000]",
			      s->elevation_m);
	return 0;
}

static int check_options(const struct astro_options *o, char *err, size_t err_size)
{
	if (!o->delta_t_auto && !in_range(o->delta_t_s, -1e6, 1e6))
		return refuse(err, err_size, "delta_t_s: %g is not in [-1e6, 1e6]", o->delta_t_s);
	if (!(fabs(o->delta_ut1_s) < 1.0))
		return refuse(err, err_size, "delta_ut1_s: %g is not in (-1, 1)", o->delta_ut1_s);
	if (!in_range(o->pressure_mbar, 0.0, 5000.0))
		return refuse(err, err_size, "pressure_mbar: %g is not in [0, 5000]", o->pressure_mbar);
	/* The refraction formula divides by 273 + T and by e0 + 5.11: these
	 * ranges keep both well away from zero. */
	if (!in_range(o->temperature_c, -100.0, 100.0))
		return refuse(err, err_size, "temperature_c: %g is not in [-100, 100]",
			      o->temperature_c);
	if (!in_range(o->horizon_refraction_deg, 0.0, 3.0))
		return refuse(err, err_size, "horizon_refraction_deg: %g is not in [0, 3]",
			      o->horizon_refraction_deg);
	return 0;
}

/* SPA's stated range in POSIX seconds: years -2000..6000 inclusive. */
#define UTC_FIRST_S (-125281123200.0)	/* -2000-01-01T00:00:00Z */
#define UTC_END_S (127206115200.0)	/* 6001-01-01T00:00:00Z */

static int check_common(const struct astro_site *site, const struct astro_options *opt,
			struct astro_options *ret_opt, char *err, size_t err_size)
{
	int r = check_site(site, err, err_size);

	if (r < 0)
		return r;
	if (opt) {
		if ((r = check_options(opt, err, err_size)) < 0)
			return r;
		*ret_opt = *opt;
	} else {
		astro_options_default(ret_opt);
	}
	return 0;
}

static int check_utc(double utc_s, char *err, size_t err_size)
{
	if (!(utc_s >= UTC_FIRST_S && utc_s < UTC_END_S))
		return refuse(err, err_size, "utc: %g s is outside years -2000..6000", utc_s);
	return 0;
}

double astro_decimal_year(double utc_s)
{
	double days = floor(utc_s / 86400.0);
	/* Find the year by the mean Gregorian year, then correct by the calendar. */
	long year = (long)floor(1970.0 + days / 365.2425);
	long start;

	while ((start = simclock_days_from_civil(year, 1, 1)) > (long)days)
		year--;
	while (simclock_days_from_civil(year + 1, 1, 1) <= (long)days)
		year++;
	start = simclock_days_from_civil(year, 1, 1);
	double len = (double)(simclock_days_from_civil(year + 1, 1, 1) - start);
	return (double)year + (utc_s / 86400.0 - (double)start) / len;
}

double astro_delta_t_s(double y)
{
	double t, u;

	if (y < -500.0 || y >= 2150.0) {
		u = (y - 1820.0) / 100.0;
		return -20.0 + 32.0 * u * u;
	}
	if (y < 500.0) {
		u = y / 100.0;
		return 10583.6 + u * (-1014.41 + u * (33.78311 + u * (-5.952053 +
		       u * (-0.1798452 + u * (0.022174192 + u * 0.0090316521)))));
	}
	if (y < 1600.0) {
		u = (y - 1000.0) / 100.0;
		return 1574.2 + u * (-556.01 + u * (71.23472 + u * (0.319781 +
		       u * (-0.8503463 + u * (-0.005050998 + u * 0.0083572073)))));
	}
	if (y < 1700.0) {
		t = y - 1600.0;
		return 120.0 + t * (-0.9808 + t * (-0.01532 + t / 7129.0));
	}
	if (y < 1800.0) {
		t = y - 1700.0;
		return 8.83 + t * (0.1603 + t * (-0.0059285 + t * (0.00013336 - t / 1174000.0)));
	}
	if (y < 1860.0) {
		t = y - 1800.0;
		return 13.72 + t * (-0.332447 + t * (0.0068612 + t * (0.0041116 + t * (-0.00037436 +
		       t * (0.0000121272 + t * (-0.0000001699 + t * 0.000000000875))))));
	}
	if (y < 1900.0) {
		t = y - 1860.0;
		return 7.62 + t * (0.5737 + t * (-0.251754 + t * (0.01680668 +
		       t * (-0.0004473624 + t / 233174.0))));
	}
	if (y < 1920.0) {
		t = y - 1900.0;
		return -2.79 + t * (1.494119 + t * (-0.0598939 + t * (0.0061966 - t * 0.000197)));
	}
	if (y < 1941.0) {
		t = y - 1920.0;
		return 21.20 + t * (0.84493 + t * (-0.076100 + t * 0.0020936));
	}
	if (y < 1961.0) {
		t = y - 1950.0;
		return 29.07 + t * (0.407 + t * (-1.0 / 233.0 + t / 2547.0));
	}
	if (y < 1986.0) {
		t = y - 1975.0;
		return 45.45 + t * (1.067 + t * (-1.0 / 260.0 - t / 718.0));
	}
	if (y < 2005.0) {
		t = y - 2000.0;
		return 63.86 + t * (0.3345 + t * (-0.060374 + t * (0.0017275 +
		       t * (0.000651814 + t * 0.00002373599))));
	}
	if (y < 2050.0) {
		t = y - 2000.0;
		return 62.92 + t * (0.32217 + t * 0.005589);
	}
	u = (y - 1820.0) / 100.0;
	return -20.0 + 32.0 * u * u - 0.5628 * (2150.0 - y);
}

static double pick_delta_t_s(const struct astro_options *o, double utc_s)
{
	return o->delta_t_auto ? astro_delta_t_s(astro_decimal_year(utc_s)) : o->delta_t_s;
}

static double jd_of(double utc_s, const struct astro_options *o)
{
	return JD_UNIX_EPOCH + (utc_s + o->delta_ut1_s) / 86400.0;
}

int astro_sun(const struct astro_site *site, double utc_s, const struct astro_options *opt,
	      struct astro_sun *ret, char *err, size_t err_size)
{
	struct astro_options o;
	struct astro_sun s;
	struct geo g;
	int r;

	if ((r = check_common(site, opt, &o, err, err_size)) < 0 ||
	    (r = check_utc(utc_s, err, err_size)) < 0)
		return r;
	s.delta_t_s = pick_delta_t_s(&o, utc_s);
	sun_geocentric(jd_of(utc_s, &o), s.delta_t_s, &g);

	s.distance_au = g.r_au;
	s.right_ascension_deg = g.alpha_deg;
	s.declination_deg = g.delta_deg;
	s.angular_radius_deg = SUN_RADIUS_1AU_DEG / g.r_au;
	s.illuminance_lx = ASTRO_SUN_ILLUMINANCE_1AU_LX / (g.r_au * g.r_au);
	double xi_deg = 8.794 / (3600.0 * g.r_au);
	topocentric(site, &o, g.alpha_deg, g.delta_deg, g.nu_deg, sind(xi_deg),
		    SUN_RADIUS_SPA_DEG, &s.geometric, &s.apparent, &s.hour_angle_deg);

	/* Equation of time, SPA A.1: the sun's mean longitude against its
	 * apparent right ascension, folded into +-20 minutes. */
	double jme = g.jme;
	double m_deg = wrap360(280.4664567 + jme * (360007.6982779 + jme * (0.03032028 +
			       jme * (1.0 / 49931.0 + jme * (-1.0 / 15300.0 - jme / 2000000.0)))));
	double e_min = 4.0 * (m_deg - 0.0057183 - g.alpha_deg + g.dpsi_deg * cosd(g.eps_deg));
	e_min = fmod(e_min, 1440.0);
	if (e_min > 20.0)
		e_min -= 1440.0;
	else if (e_min < -20.0)
		e_min += 1440.0;
	s.equation_of_time_min = e_min;
	*ret = s;
	return 0;
}

/* ------------------------------------------------------------------------ */
/* Moon. */

double astro_moon_illuminance_lx(double phase_angle_deg, double moon_distance_km,
				 double sun_distance_au)
{
	double a = fabs(phase_angle_deg);

	if (!(a < 180.0) || !(moon_distance_km > 0.0) || !(sun_distance_au > 0.0))
		return 0.0;
	double mag = -12.73 + 0.026 * a + 4e-9 * a * a * a * a;
	double dm = MOON_MEAN_DISTANCE_KM / moon_distance_km;
	return ASTRO_MOON_ILLUMINANCE_MAG0_LX * pow(10.0, -0.4 * mag) * dm * dm /
	       (sun_distance_au * sun_distance_au);
}

/* The moon reflects sunlight but reddens it: its colour index B-V is 0.92
 * against the sun's 0.65 (Allen), so its reflectance at 440 nm is
 * 10^(-0.4 * 0.27) = 0.78 of that at 550 nm. Taking the reflectance as
 * linear in wavelength over the visible (as lunar spectra roughly are)
 * gives 1.26 at 680 nm; normalized to Rec. 709 luminance that is about
 * (1.212, 0.962, 0.750) of the sunlight's colour. */
static void moon_color(double ret[3])
{
	double blue = pow(10.0, -0.4 * (0.92 - 0.65));
	double slope_per_nm = (1.0 - blue) / (550.0 - 440.0);
	double red = 1.0 + slope_per_nm * (680.0 - 550.0);
	double y = 0.2126 * red + 0.7152 * 1.0 + 0.0722 * blue;

	ret[0] = red / y;
	ret[1] = 1.0 / y;
	ret[2] = blue / y;
}

/* Geocentric ecliptic longitude and latitude (degrees, mean equinox of date)
 * and distance (km) at JCE, Meeus ch. 47. */
static void moon_geocentric(double t, double *ret_lambda_deg, double *ret_beta_deg,
			    double *ret_distance_km)
{
	double t2 = t * t, t3 = t2 * t, t4 = t3 * t;
	double lp = 218.3164477 + 481267.88123421 * t - 0.0015786 * t2 + t3 / 538841.0 -
		    t4 / 65194000.0;
	double d = 297.8501921 + 445267.1114034 * t - 0.0018819 * t2 + t3 / 545868.0 -
		   t4 / 113065000.0;
	double m = 357.5291092 + 35999.0502909 * t - 0.0001536 * t2 + t3 / 24490000.0;
	double mp = 134.9633964 + 477198.8675055 * t + 0.0087414 * t2 + t3 / 69699.0 -
		    t4 / 14712000.0;
	double f = 93.2720950 + 483202.0175233 * t - 0.0036539 * t2 - t3 / 3526000.0 +
		   t4 / 863310000.0;
	double a1 = 119.75 + 131.849 * t;
	double a2 = 53.09 + 479264.290 * t;
	double a3 = 313.45 + 481266.484 * t;
	/* The eccentricity of the earth's orbit shrinks the terms in M. */
	double e = 1.0 - 0.002516 * t - 0.0000074 * t2;
	double e_pow[3] = { 1.0, e, e * e };
	double sl = 0.0, sr = 0.0, sb = 0.0;

	d = wrap360(d) * DEG, m = wrap360(m) * DEG, mp = wrap360(mp) * DEG, f = wrap360(f) * DEG;
	for (size_t i = 0; i < N(moon_lr); i++) {
		const struct moon_lr_term *k = &moon_lr[i];
		double arg = k->d * d + k->m * m + k->mp * mp + k->f * f;
		double ef = e_pow[abs(k->m)];
		sl += k->l * ef * sin(arg);
		sr += k->r * ef * cos(arg);
	}
	for (size_t i = 0; i < N(moon_b); i++) {
		const struct moon_b_term *k = &moon_b[i];
		double arg = k->d * d + k->m * m + k->mp * mp + k->f * f;
		sb += k->b * e_pow[abs(k->m)] * sin(arg);
	}
	lp = wrap360(lp);
	sl += 3958.0 * sind(a1) + 1962.0 * sin(lp * DEG - f) + 318.0 * sind(a2);
	sb += -2235.0 * sind(lp) + 382.0 * sind(a3) + 175.0 * sin(a1 * DEG - f) +
	      175.0 * sin(a1 * DEG + f) + 127.0 * sin(lp * DEG - mp) - 115.0 * sin(lp * DEG + mp);

	*ret_lambda_deg = wrap360(lp + sl / 1e6);
	*ret_beta_deg = sb / 1e6;
	*ret_distance_km = 385000.56 + sr / 1000.0;
}

/* Observer to body: the geocentric vector less the observer's, in the
 * equatorial frame turned so that the observer's meridian is x. */
static double topocentric_distance_km(const struct astro_site *site, double distance_km,
				      double alpha_deg, double delta_deg, double nu_deg)
{
	double x, y;

	observer_xy(site, &x, &y);
	double h_deg = nu_deg + site->lon_deg - alpha_deg;
	double bx = distance_km * cosd(delta_deg) * cosd(h_deg) - x * EARTH_EQUATORIAL_RADIUS_KM;
	double by = distance_km * cosd(delta_deg) * sind(h_deg);
	double bz = distance_km * sind(delta_deg) - y * EARTH_EQUATORIAL_RADIUS_KM;
	return sqrt(bx * bx + by * by + bz * bz);
}

int astro_moon(const struct astro_site *site, double utc_s, const struct astro_options *opt,
	       struct astro_moon *ret, char *err, size_t err_size)
{
	struct astro_options o;
	struct astro_moon m;
	struct geo sun;
	double alpha_deg, delta_deg;
	int r;

	if ((r = check_common(site, opt, &o, err, err_size)) < 0 ||
	    (r = check_utc(utc_s, err, err_size)) < 0)
		return r;
	m.delta_t_s = pick_delta_t_s(&o, utc_s);
	/* The sun's geocentric position comes along: it shares the time
	 * arguments, nutation and sidereal time, and gives the phase. */
	sun_geocentric(jd_of(utc_s, &o), m.delta_t_s, &sun);

	moon_geocentric(sun.jce, &m.longitude_deg, &m.latitude_deg, &m.distance_km);
	m.apparent_longitude_deg = wrap360(m.longitude_deg + sun.dpsi_deg);
	ecliptic_to_equatorial(m.apparent_longitude_deg, m.latitude_deg, sun.eps_deg,
			       &alpha_deg, &delta_deg);
	m.right_ascension_deg = alpha_deg;
	m.declination_deg = delta_deg;

	double sin_parallax = EARTH_EQUATORIAL_RADIUS_KM / m.distance_km;
	/* The moon's radius is 0.2725 of the earth's: its angular radius is
	 * 0.2725 of its parallax; refraction stops below that, as for the sun. */
	topocentric(site, &o, alpha_deg, delta_deg, sun.nu_deg, sin_parallax,
		    0.2725 * asind(sin_parallax), &m.geometric, &m.apparent, NULL);

	m.topocentric_distance_km = topocentric_distance_km(site, m.distance_km, alpha_deg,
							    delta_deg, sun.nu_deg);

	/* Meeus 48.2-48.3 with the sun's apparent place and distance. */
	double r_km = sun.r_au * AU_KM;
	double cos_psi = sind(sun.delta_deg) * sind(delta_deg) +
			 cosd(sun.delta_deg) * cosd(delta_deg) * cosd(sun.alpha_deg - alpha_deg);
	double psi_deg = acos(fmin(1.0, fmax(-1.0, cos_psi))) / DEG;
	m.elongation_deg = psi_deg;
	m.phase_angle_deg = atan2d(r_km * sind(psi_deg), m.distance_km - r_km * cos_psi);
	m.illuminated_fraction = (1.0 + cosd(m.phase_angle_deg)) / 2.0;
	m.waxing = wrap360(m.apparent_longitude_deg - sun.lambda_deg) < 180.0;
	m.angular_radius_deg = asind(MOON_RADIUS_KM / m.topocentric_distance_km);
	m.illuminance_lx = astro_moon_illuminance_lx(m.phase_angle_deg, m.topocentric_distance_km,
						     sun.r_au);
	moon_color(m.color);
	*ret = m;
	return 0;
}

/* ------------------------------------------------------------------------ */
/* Sun rise, transit and set, SPA appendix A.2, from local midnight. */

/* The three daily positions (at 0 TT of the day before, the day, the day
 * after local midnight) and the sidereal time at local midnight. */
struct rts_day {
	double nu_deg;
	double alpha_deg[3], delta_deg[3];
	double delta_t_s;
	double lat_deg, lon_deg;
};

/* Newton steps for an event, and the step (days, 1 ms) that ends them. */
#define RTS_MAX_STEPS 5
#define RTS_STEP_DONE 1e-8

/* Interpolated right ascension or declination at n days from the middle
 * point, A.2.8. Differences of right ascension are taken the short way
 * round, where the report folds them into [0, 1) and loses a degree at
 * the wrap. */
static double interpolate(const double v[3], double n, bool angle)
{
	double a = v[1] - v[0], b = v[2] - v[1];

	if (angle)
		a = wrap180(a), b = wrap180(b);
	return v[1] + n * (a + b + (b - a) * n) / 2.0;
}

/* Elevation of the sun's centre (geocentric) at day fraction m, with its
 * local hour angle and declination there, A.2.6-A.2.10. */
static double rts_elevation(const struct rts_day *d, double m, double *ret_h_deg,
			    double *ret_delta_deg)
{
	double nu = d->nu_deg + 360.985647 * m;
	double n = m + d->delta_t_s / 86400.0;
	double alpha = interpolate(d->alpha_deg, n, true);
	double delta = interpolate(d->delta_deg, n, false);
	double h = wrap180(nu + d->lon_deg - alpha);

	*ret_h_deg = h;
	*ret_delta_deg = delta;
	return asind(sind(d->lat_deg) * sind(delta) + cosd(d->lat_deg) * cosd(delta) * cosd(h));
}

static void rise_set(const struct rts_day *d, double m0, double threshold_deg, double midnight_s,
		     double dut1_s, struct astro_rise_set *ret)
{
	double phi = d->lat_deg, delta0 = d->delta_deg[1];
	double arg = (sind(threshold_deg) - sind(phi) * sind(delta0)) / (cosd(phi) * cosd(delta0));

	ret->threshold_deg = threshold_deg;
	ret->rise_utc_s = ret->set_utc_s = NAN;
	/* Written so that a NaN (a pole, where cos(phi) is 0 and sin(phi) is
	 * +-1) cannot fall through as "rises and sets". */
	if (!(arg >= -1.0)) {
		ret->kind = ASTRO_ALWAYS_ABOVE;
		return;
	}
	if (!(arg <= 1.0)) {
		ret->kind = ASTRO_ALWAYS_BELOW;
		return;
	}
	ret->kind = ASTRO_RISES_AND_SETS;
	double h0_deg = acos(arg) / DEG;
	double m[2] = { wrap01(m0 - h0_deg / 360.0), wrap01(m0 + h0_deg / 360.0) };
	double *out[2] = { &ret->rise_utc_s, &ret->set_utc_s };
	for (int i = 0; i < 2; i++) {
		/* A.2.12-A.2.13 is one Newton step on the elevation; the report
		 * stops there, which leaves up to ~0.01 deg (seconds) at the
		 * twilights where the first guess is far. Repeating the step
		 * until it stalls changes the report's own example by < 0.1 s. */
		double frac = m[i];
		for (int k = 0; k < RTS_MAX_STEPS; k++) {
			double h_deg, delta_deg;
			double e = rts_elevation(d, frac, &h_deg, &delta_deg);
			double step = (e - threshold_deg) /
				      (360.0 * cosd(delta_deg) * cosd(phi) * sind(h_deg));
			if (!isfinite(step))
				break;
			frac += step;
			if (fabs(step) < RTS_STEP_DONE)
				break;
		}
		*out[i] = midnight_s + frac * 86400.0 - dut1_s;
	}
}

static int check_date(const struct astro_date *dt, char *err, size_t err_size)
{
	if (!dt)
		return refuse(err, err_size, "date: missing");
	if (dt->year < -2000 || dt->year > 6000)
		return refuse(err, err_size, "year: %d is not in [-2000, 6000]", dt->year);
	if (dt->month < 1 || dt->month > 12)
		return refuse(err, err_size, "month: %d is not in [1, 12]", dt->month);
	if (!simclock_valid_date(dt->year, dt->month, dt->day))
		return refuse(err, err_size, "day: %d is not a day of %04d-%02d", dt->day, dt->year,
			      dt->month);
	if (dt->utc_offset_min < -1080 || dt->utc_offset_min > 1080)
		return refuse(err, err_size, "utc_offset_min: %d is not in [-1080, 1080]",
			      dt->utc_offset_min);
	return 0;
}

int astro_sun_times(const struct astro_site *site, const struct astro_date *date,
		    const struct astro_options *opt, struct astro_times *ret,
		    char *err, size_t err_size)
{
	struct astro_options o;
	struct astro_times t;
	struct rts_day d;
	struct geo g;
	int r;

	if ((r = check_common(site, opt, &o, err, err_size)) < 0 ||
	    (r = check_date(date, err, err_size)) < 0)
		return r;
	double midnight_s = (double)simclock_days_from_civil(date->year, date->month, date->day) *
			    86400.0 - date->utc_offset_min * 60.0;
	/* The day's local midnight in UT1: the report's 0 h UT, moved. */
	double jd0 = JD_UNIX_EPOCH + midnight_s / 86400.0;

	d.delta_t_s = pick_delta_t_s(&o, midnight_s + 43200.0);
	d.lat_deg = site->lat_deg;
	d.lon_deg = site->lon_deg;
	/* A.2.1-A.2.2: sidereal time at midnight, positions at 0 TT. */
	for (int i = 0; i < 3; i++) {
		sun_geocentric(jd0 + i - 1, 0.0, &g);
		d.alpha_deg[i] = g.alpha_deg;
		d.delta_deg[i] = g.delta_deg;
		if (i == 1)
			d.nu_deg = g.nu_deg;
	}
	double m0 = wrap01((d.alpha_deg[1] - d.lon_deg - d.nu_deg) / 360.0);
	/* A.2.11, repeated like the rise and set steps. */
	double transit = m0;
	for (int k = 0; k < RTS_MAX_STEPS; k++) {
		double h_deg, delta_deg;
		rts_elevation(&d, transit, &h_deg, &delta_deg);
		transit -= h_deg / 360.0;
		if (fabs(h_deg / 360.0) < RTS_STEP_DONE)
			break;
	}
	t.transit_utc_s = midnight_s + transit * 86400.0 - o.delta_ut1_s;

	rise_set(&d, m0, -(SUN_RADIUS_SPA_DEG + o.horizon_refraction_deg), midnight_s,
		 o.delta_ut1_s, &t.sunrise_sunset);
	rise_set(&d, m0, -6.0, midnight_s, o.delta_ut1_s, &t.civil);
	rise_set(&d, m0, -12.0, midnight_s, o.delta_ut1_s, &t.nautical);
	rise_set(&d, m0, -18.0, midnight_s, o.delta_ut1_s, &t.astronomical);

	struct astro_sun at_noon;
	if ((r = astro_sun(site, t.transit_utc_s, &o, &at_noon, err, err_size)) < 0)
		return r;
	t.transit_elevation_deg = at_noon.geometric.elevation_deg;
	*ret = t;
	return 0;
}
