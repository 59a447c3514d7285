/* skycloud.h - the cloud field: up to four layers of cloud over a periodic
 * region around the observer, their coverage, density, occlusion of the
 * sky and optical depth along a ray; one definition for skyd, libsky and
 * the path tracer. proto/glsl/skycloud.glsl is the same functions in GLSL
 * (test_glsl_cloud checks the pair). The model, its formulas and sources:
 * docs/clouds.md.
 *
 * Header-only, no allocation, nothing of libc beyond <math.h> and
 * <stdint.h>. Included plainly it is the float build, skycloud_*; with
 * SKYCLOUD_DOUBLE defined (to 1) before the include it is the double
 * build, skycloudd_* (the path tracer's), and a file may include both.
 * SKYCLOUD_REAL is the type of the build being defined.
 *
 * Determinism: the lattice hash is integer arithmetic; the coverage and
 * density use only +, -, *, floor, min and max of floats, each correctly
 * rounded, with every constant a power of two or exact in a float, so
 * that the same inputs give the same bits on every IEEE 754 host and, with
 * GLSL's precise, on the device. That holds when the compiler fuses no
 * multiply-add: ISO C modes (-std=c17) do not; GNU modes on a machine
 * with FMA need -ffp-contract=off. sqrt and exp (altitudes, occlusion)
 * are only within their ulps.
 *
 * Conventions: lengths in km (keys in m are the caller's), the observer's
 * east-north-up frame; a point's field coordinates are its east and north
 * km from the ground point under the observer, its altitude is above the
 * ground there; a layer is the spherical shell [base, top]. The field at
 * simulated time t is the field at time 0 moved by the wind: it is
 * evaluated at (east, north) - offset, offset = skycloud_wind_offset_km.
 */
#ifndef SKYD_SKYCLOUD_COMMON_H
#define SKYD_SKYCLOUD_COMMON_H

#include <math.h>
#include <stdint.h>

/* Bumped with any change to what these functions return for the same
 * arguments; skycloud.glsl's SKYCLOUD_GLSL_VERSION follows. */
#define SKYCLOUD_VERSION 1

#define SKYCLOUD_MAX_LAYERS 4
/* The field repeats every SKYCLOUD_PERIOD_KM east and north (and up): the
 * wind's offset is taken modulo it in double, so that a float holds it to
 * 6 cm. Twice the widest region (cloud_extent_km at most 512). */
#define SKYCLOUD_PERIOD_KM 1024
#define SKYCLOUD_COVERAGE_OCTAVES 5
#define SKYCLOUD_DETAIL_OCTAVES 3
/* Cells per km of the finest lattice allowed: the fixed-point position
 * (16 fraction bits of a cell) must fit an int32 over a whole period. */
#define SKYCLOUD_MAX_SCALE 16

enum skycloud_type {
	SKYCLOUD_STRATUS = 0,
	SKYCLOUD_STRATOCUMULUS = 1,
	SKYCLOUD_CUMULUS = 2,
	SKYCLOUD_CUMULONIMBUS = 3,
	SKYCLOUD_ALTOSTRATUS = 4,
	SKYCLOUD_CIRRUS = 5,
	SKYCLOUD_N_TYPES = 6,
};

/* One type of cloud: docs/clouds.md, "The types", says where each number
 * comes from. The density profile over the height fraction hf of a layer
 * rises over bottom_fade and falls over top_fade (smoothsteps); anvil
 * widens the coverage toward the top (cumulonimbus). Cell sizes are
 * powers of two in km. */
struct skycloud_type_info {
	const char *name;
	float bottom_fade, top_fade;	/* fractions of the thickness; sum <= 1 */
	float anvil;			/* coverage margin added at the top, times hf^2 */
	float extinction_per_km;	/* at density 1, 550 nm (grey in the visible) */
	float albedo;			/* single scattering */
	float phase_g;			/* Henyey-Greenstein asymmetry */
	float coverage_cell_km;		/* the coverage's coarsest lattice cell */
	float coverage_edge;		/* soft edge of the coverage, in fBm units */
	float detail_cell_km;		/* the detail noise's coarsest cell */
	float erosion;			/* how much the detail noise takes off, [0, 1) */
	float thickness_m;		/* typical: a METAR layer's top above its base */
	float base_m;			/* typical base above the ground */
};

static const struct skycloud_type_info skycloud_types[SKYCLOUD_N_TYPES] = {
	[SKYCLOUD_STRATUS] = { "stratus", 0.10f, 0.20f, 0.0f, 90.0f, 1.0f, 0.85f,
			       16.0f, 0.08f, 0.5f, 0.25f, 400.0f, 300.0f },
	[SKYCLOUD_STRATOCUMULUS] = { "stratocumulus", 0.15f, 0.30f, 0.0f, 30.0f, 1.0f, 0.85f,
				     8.0f, 0.04f, 0.5f, 0.40f, 400.0f, 1000.0f },
	[SKYCLOUD_CUMULUS] = { "cumulus", 0.05f, 0.50f, 0.0f, 60.0f, 1.0f, 0.85f,
			       2.0f, 0.02f, 0.25f, 0.50f, 1500.0f, 1000.0f },
	[SKYCLOUD_CUMULONIMBUS] = { "cumulonimbus", 0.05f, 0.15f, 6.0f, 38.0f, 1.0f, 0.85f,
				    8.0f, 0.02f, 0.5f, 0.35f, 8000.0f, 800.0f },
	[SKYCLOUD_ALTOSTRATUS] = { "altostratus", 0.15f, 0.25f, 0.0f, 8.0f, 1.0f, 0.85f,
				   16.0f, 0.08f, 1.0f, 0.20f, 1500.0f, 3500.0f },
	[SKYCLOUD_CIRRUS] = { "cirrus", 0.25f, 0.35f, 0.0f, 0.5f, 1.0f, 0.75f,
			      4.0f, 0.06f, 1.0f, 0.60f, 1500.0f, 8000.0f },
};

/* The coverage fBm's quantiles: entry k is the value below which a
 * fraction k / 64 of the field lies (0 and 64: the least and the most
 * seen), measured by tools/cloudstat over 8 seeds x 4 layers x a whole
 * period (docs/clouds.md, "Cover"). A layer of cover c is cloudy where
 * the fBm exceeds the quantile at 1 - c. */
#define SKYCLOUD_QUANTILES 64
static const double skycloud_quantile[SKYCLOUD_QUANTILES + 1] = {
	-1.114193, -0.584345, -0.516116, -0.470315, -0.433748, -0.403023,
	-0.376308, -0.352234, -0.329904, -0.309150, -0.289670, -0.271328,
	-0.253957, -0.237394, -0.221476, -0.206168, -0.191352, -0.177070,
	-0.163203, -0.149805, -0.136824, -0.124179, -0.111839, -0.099756,
	-0.087883, -0.076253, -0.064831, -0.053605, -0.042576, -0.031704,
	-0.020997, -0.010414, 0.000014, 0.010476, 0.021048, 0.031741,
	0.042619, 0.053670, 0.064919, 0.076353, 0.087956, 0.099787,
	0.111877, 0.124219, 0.136826, 0.149779, 0.163164, 0.176974,
	0.191256, 0.206036, 0.221366, 0.237341, 0.253893, 0.271292,
	0.289630, 0.309146, 0.329942, 0.352226, 0.376313, 0.403041,
	0.433767, 0.470202, 0.516066, 0.584593, 1.122589,
};

/* The lattice hash: pcg3d of Jarzynski and Olano, "Hash Functions for GPU
 * Rendering" (JCGT 2020): integer multiply, add, xor and shift, the same
 * bits on every host and device. */
static inline void skycloud_pcg3d(uint32_t v[3])
{
	v[0] = v[0] * 1664525u + 1013904223u;
	v[1] = v[1] * 1664525u + 1013904223u;
	v[2] = v[2] * 1664525u + 1013904223u;
	v[0] += v[1] * v[2];
	v[1] += v[2] * v[0];
	v[2] += v[0] * v[1];
	v[0] ^= v[0] >> 16;
	v[1] ^= v[1] >> 16;
	v[2] ^= v[2] >> 16;
	v[0] += v[1] * v[2];
	v[1] += v[2] * v[0];
	v[2] += v[0] * v[1];
}

/* The key of one octave of one noise of a layer: its streams are
 * SKYCLOUD_STREAM_COVERAGE or _DETAIL plus the layer's index. */
#define SKYCLOUD_STREAM_COVERAGE 0x100u
#define SKYCLOUD_STREAM_DETAIL 0x200u
static inline void skycloud_key(uint32_t seed, uint32_t stream, uint32_t octave, uint32_t ret[3])
{
	ret[0] = seed;
	ret[1] = stream;
	ret[2] = octave;
	skycloud_pcg3d(ret);
}

static inline uint32_t skycloud_hash3(uint32_t i, uint32_t j, uint32_t k, const uint32_t key[3])
{
	uint32_t v[3] = { i ^ key[0], j ^ key[1], k ^ key[2] };

	skycloud_pcg3d(v);
	return v[0];
}

/* The fBm value below which a fraction u of the field lies (linear
 * between the table's entries); the coverage threshold of cover c is
 * skycloud_threshold(1 - c). Double: the same on every host. */
static inline double skycloud_threshold(double u)
{
	if (!(u > 0.0))
		return -1e30;	/* overcast: every value exceeds it */
	if (u >= 1.0)
		return 1e30;	/* clear */
	double x = u * SKYCLOUD_QUANTILES;
	int k = (int)x;
	double f = x - k;
	return skycloud_quantile[k] + f * (skycloud_quantile[k + 1] - skycloud_quantile[k]);
}

/* sin and cos of an angle in degrees from +, * and one exact reduction to
 * [-45, 45]: the same bits on every IEEE host, where libm's may differ in
 * the last one. Taylor to the 18th power: under 1e-17 there. */
static inline void skycloud_sincos_deg(double deg, double *ret_sin, double *ret_cos)
{
	double d = fmod(deg, 360.0);
	if (d < 0.0)
		d += 360.0;
	int q = (int)floor(d / 90.0 + 0.5);
	double x = (d - 90.0 * q) * (3.14159265358979323846 / 180.0), x2 = x * x;
	double s = x, c = 1.0, ts = x, tc = 1.0;
	for (int n = 1; n <= 9; n++) {
		ts *= -x2 / ((2 * n) * (2 * n + 1));
		tc *= -x2 / ((2 * n - 1) * (2 * n));
		s += ts;
		c += tc;
	}
	switch (q & 3) {
	case 0: *ret_sin = s; *ret_cos = c; break;
	case 1: *ret_sin = c; *ret_cos = -s; break;
	case 2: *ret_sin = -s; *ret_cos = -c; break;
	default: *ret_sin = -c; *ret_cos = s; break;
	}
}

/* Where the wind has carried the field at simulated time time_s (seconds
 * since the POSIX epoch): the wind blows from wind_dir_deg (clockwise from
 * north, as METAR) at wind_speed_mps, so the field moves toward
 * wind_dir_deg + 180. East and north km in [0, SKYCLOUD_PERIOD_KM), in
 * double: a float of the product, some 1e7 km, would lose a kilometre. */
static inline void skycloud_wind_offset_km(double wind_dir_deg, double wind_speed_mps,
					   double time_s, double ret_km[2])
{
	double s, c;

	skycloud_sincos_deg(wind_dir_deg, &s, &c);
	double v[2] = { -wind_speed_mps * s, -wind_speed_mps * c };
	for (int i = 0; i < 2; i++) {
		double o = fmod(v[i] * time_s * 1e-3, (double)SKYCLOUD_PERIOD_KM);
		if (o < 0.0)
			o += SKYCLOUD_PERIOD_KM;
		ret_km[i] = o >= SKYCLOUD_PERIOD_KM ? 0.0 : o + 0.0;	/* + 0: no -0 */
	}
}

/* Integral over hf in [0, 1] of the profile (two smoothsteps that do not
 * overlap): the column's share of a full-density slab. */
static inline double skycloud_profile_integral(const struct skycloud_type_info *t)
{
	return 1.0 - 0.5 * ((double)t->bottom_fade + (double)t->top_fade);
}

#endif /* SKYD_SKYCLOUD_COMMON_H */

/* ---- one precision: float (skycloud_*) or double (skycloudd_*) ---- */

#if defined(SKYCLOUD_DOUBLE) && !defined(SKYD_SKYCLOUD_D_H)
#define SKYD_SKYCLOUD_D_H
#define SKYCLOUD_REAL double
#define SKYCLOUD_FN(name) skycloudd_##name
#define SKYCLOUD_FLOOR floor
#define SKYCLOUD_SQRT sqrt
#define SKYCLOUD_EXP exp
#define SKYCLOUD_BODY
#elif !defined(SKYCLOUD_DOUBLE) && !defined(SKYD_SKYCLOUD_F_H)
#define SKYD_SKYCLOUD_F_H
#define SKYCLOUD_REAL float
#define SKYCLOUD_FN(name) skycloud_##name
#define SKYCLOUD_FLOOR floorf
#define SKYCLOUD_SQRT sqrtf
#define SKYCLOUD_EXP expf
#define SKYCLOUD_BODY
#endif

#ifdef SKYCLOUD_BODY
#undef SKYCLOUD_BODY
#define R_ SKYCLOUD_REAL
#define FN_ SKYCLOUD_FN

/* One layer as the functions take it, from skycloud_layer_init. */
struct FN_(layer) {
	int32_t type;			/* enum skycloud_type */
	uint32_t seed;			/* cloud_seed */
	uint32_t index;			/* 0..3: the layer's own noise */
	R_ cover;			/* [0, 1] */
	R_ base_km, top_km;		/* above the ground under the observer */
	R_ inv_thickness_per_km;	/* 1 / (top - base) */
	R_ threshold;			/* coverage threshold, fBm units */
	R_ inv_edge;			/* 1 / the soft edge's width */
	R_ inv_bottom_fade, inv_top_fade, anvil;
	R_ extinction_per_km;
	R_ erosion, inv_keep;		/* 1 / (1 - erosion) */
	R_ coverage_scale;		/* cells per km of the coarsest octave */
	R_ detail_scale;
	R_ profile_integral;		/* skycloud_profile_integral of the type */
};

/* Fills L for a layer of type (enum skycloud_type; clamped into range),
 * cover in [0, 1], base and top in km (top above base), the field's seed
 * and the layer's index 0..3. Every derived value is computed in double
 * and rounded once, so that both builds hold the same numbers. */
static inline void FN_(layer_init)(struct FN_(layer) *L, int type, double cover, double base_km,
				   double top_km, uint32_t seed, uint32_t index)
{
	if (type < 0 || type >= SKYCLOUD_N_TYPES)
		type = SKYCLOUD_STRATOCUMULUS;
	const struct skycloud_type_info *t = &skycloud_types[type];
	double c = cover > 1.0 ? 1.0 : cover > 0.0 ? cover : 0.0;
	double thick = top_km > base_km ? top_km - base_km : 1e-3;

	L->type = type;
	L->seed = seed;
	L->index = index;
	L->cover = (R_)c;
	L->base_km = (R_)base_km;
	L->top_km = (R_)(base_km + thick);
	L->inv_thickness_per_km = (R_)(1.0 / thick);
	L->threshold = (R_)skycloud_threshold(1.0 - c);
	L->inv_edge = (R_)(1.0 / t->coverage_edge);
	L->inv_bottom_fade = (R_)(1.0 / t->bottom_fade);
	L->inv_top_fade = (R_)(1.0 / t->top_fade);
	L->anvil = (R_)t->anvil;
	L->extinction_per_km = (R_)t->extinction_per_km;
	L->erosion = (R_)t->erosion;
	L->inv_keep = (R_)(1.0 / (1.0 - t->erosion));
	L->coverage_scale = (R_)(1.0 / t->coverage_cell_km);
	L->detail_scale = (R_)(1.0 / t->detail_cell_km);
	L->profile_integral = (R_)skycloud_profile_integral(t);
}

static inline R_ FN_(saturate)(R_ x)
{
	return x < (R_)0 ? (R_)0 : x > (R_)1 ? (R_)1 : x;
}

/* p wrapped into [0, period): exact for |p| < 2^14 km (a power-of-two
 * period); the lattice masks what rounds up to the period itself. */
static inline R_ FN_(wrap)(R_ p)
{
	return p - (R_)SKYCLOUD_PERIOD_KM * SKYCLOUD_FLOOR(p * (R_)(1.0 / SKYCLOUD_PERIOD_KM));
}

/* The lattice cell of a wrapped coordinate at s cells per km (a power of
 * two up to SKYCLOUD_MAX_SCALE) and the fraction in it, in fixed point
 * with 16 bits of a cell: the fraction is exact and never subnormal. */
static inline void FN_(cell)(R_ p, R_ s, uint32_t *ret_i, uint32_t *ret_i1, R_ *ret_t)
{
	uint32_t mask = (uint32_t)((R_)SKYCLOUD_PERIOD_KM * s) - 1u;
	uint32_t u = (uint32_t)(int32_t)SKYCLOUD_FLOOR(p * s * (R_)65536);

	*ret_i = (u >> 16) & mask;
	*ret_i1 = ((u >> 16) + 1u) & mask;
	*ret_t = (R_)(u & 0xffffu) * (R_)(1.0 / 65536.0);
}

/* Perlin's quintic fade. */
static inline R_ FN_(fade)(R_ t)
{
	return t * t * t * (t * (t * (R_)6 - (R_)15) + (R_)10);
}

/* A 2-D gradient of eight, (+-1, +-0.5) and (+-0.5, +-1): equal lengths,
 * products with the fraction exact. */
static inline R_ FN_(grad2)(uint32_t h, R_ x, R_ y)
{
	R_ gx = (h & 0x20000000u) ? (R_)0.5 : (R_)1;
	R_ gy = (h & 0x20000000u) ? (R_)1 : (R_)0.5;

	if (h & 0x40000000u)
		gx = -gx;
	if (h & 0x80000000u)
		gy = -gy;
	return gx * x + gy * y;
}

/* Perlin's twelve edge gradients of a cube (2002), by the top 4 bits. */
static inline R_ FN_(grad3)(uint32_t h, R_ x, R_ y, R_ z)
{
	uint32_t k = h >> 28;
	R_ u = k < 8u ? x : y;
	R_ v = k < 4u ? y : (k == 12u || k == 14u) ? x : z;

	return ((k & 1u) ? -u : u) + ((k & 2u) ? -v : v);
}

/* Gradient noise in 2-D at wrapped (x, y), s cells per km. */
static inline R_ FN_(noise2)(R_ x, R_ y, R_ s, const uint32_t key[3])
{
	uint32_t i0, i1, j0, j1;
	R_ tx, ty;

	FN_(cell)(x, s, &i0, &i1, &tx);
	FN_(cell)(y, s, &j0, &j1, &ty);
	R_ n00 = FN_(grad2)(skycloud_hash3(i0, j0, 0u, key), tx, ty);
	R_ n10 = FN_(grad2)(skycloud_hash3(i1, j0, 0u, key), tx - (R_)1, ty);
	R_ n01 = FN_(grad2)(skycloud_hash3(i0, j1, 0u, key), tx, ty - (R_)1);
	R_ n11 = FN_(grad2)(skycloud_hash3(i1, j1, 0u, key), tx - (R_)1, ty - (R_)1);
	R_ fx = FN_(fade)(tx), fy = FN_(fade)(ty);
	R_ a = n00 + fx * (n10 - n00);
	R_ b = n01 + fx * (n11 - n01);
	return a + fy * (b - a);
}

/* Gradient noise in 3-D at wrapped (x, y, z). */
static inline R_ FN_(noise3)(R_ x, R_ y, R_ z, R_ s, const uint32_t key[3])
{
	uint32_t i[2], j[2], k[2];
	R_ tx, ty, tz;

	FN_(cell)(x, s, &i[0], &i[1], &tx);
	FN_(cell)(y, s, &j[0], &j[1], &ty);
	FN_(cell)(z, s, &k[0], &k[1], &tz);
	R_ fx = FN_(fade)(tx), fy = FN_(fade)(ty), fz = FN_(fade)(tz);
	R_ plane[2];
	for (int c = 0; c < 2; c++) {
		R_ dz = tz - (R_)c;
		R_ n00 = FN_(grad3)(skycloud_hash3(i[0], j[0], k[c], key), tx, ty, dz);
		R_ n10 = FN_(grad3)(skycloud_hash3(i[1], j[0], k[c], key), tx - (R_)1, ty, dz);
		R_ n01 = FN_(grad3)(skycloud_hash3(i[0], j[1], k[c], key), tx, ty - (R_)1, dz);
		R_ n11 = FN_(grad3)(skycloud_hash3(i[1], j[1], k[c], key), tx - (R_)1, ty - (R_)1, dz);
		R_ a = n00 + fx * (n10 - n00);
		R_ b = n01 + fx * (n11 - n01);
		plane[c] = a + fy * (b - a);
	}
	return plane[0] + fz * (plane[1] - plane[0]);
}

/* The coverage fBm of layer L at wrapped field coordinates: octaves of
 * gradient noise at doubling frequency and halving amplitude, summed
 * coarse to fine. */
static inline R_ FN_(coverage_fbm)(const struct FN_(layer) *L, R_ x, R_ y)
{
	R_ sum = (R_)0, amp = (R_)1, s = L->coverage_scale;
	uint32_t key[3];

	for (uint32_t o = 0; o < SKYCLOUD_COVERAGE_OCTAVES; o++) {
		skycloud_key(L->seed, SKYCLOUD_STREAM_COVERAGE + L->index, o, key);
		sum += amp * FN_(noise2)(x, y, s, key);
		amp *= (R_)0.5;
		s *= (R_)2;
	}
	return sum;
}

/* The coverage margin at field coordinates (x, y) km with the wind's
 * offset: (fBm - threshold) / edge. Cloud where it is > 0; the coverage
 * is saturate(margin + 0.5). */
static inline R_ FN_(coverage_margin)(const struct FN_(layer) *L, R_ x, R_ y, const R_ offset_km[2])
{
	R_ px = FN_(wrap)(x - offset_km[0]), py = FN_(wrap)(y - offset_km[1]);

	return (FN_(coverage_fbm)(L, px, py) - L->threshold) * L->inv_edge;
}

static inline R_ FN_(coverage)(const struct FN_(layer) *L, R_ x, R_ y, const R_ offset_km[2])
{
	return FN_(saturate)(FN_(coverage_margin)(L, x, y, offset_km) + (R_)0.5);
}

/* The detail noise in [0, 1]: billowy (the octaves' magnitudes), at
 * wrapped coordinates and altitude. */
#define SKYCLOUD_DETAIL_GAIN 1.5
static inline R_ FN_(detail)(const struct FN_(layer) *L, R_ x, R_ y, R_ z)
{
	R_ sum = (R_)0, amp = (R_)1, s = L->detail_scale;
	uint32_t key[3];

	for (uint32_t o = 0; o < SKYCLOUD_DETAIL_OCTAVES; o++) {
		skycloud_key(L->seed, SKYCLOUD_STREAM_DETAIL + L->index, o, key);
		R_ n = FN_(noise3)(x, y, z, s, key);
		sum += amp * (n < (R_)0 ? -n : n);
		amp *= (R_)0.5;
		s *= (R_)2;
	}
	return FN_(saturate)(sum * (R_)SKYCLOUD_DETAIL_GAIN);
}

/* The vertical profile at height fraction hf in (0, 1). */
static inline R_ FN_(profile)(const struct FN_(layer) *L, R_ hf)
{
	R_ a = FN_(saturate)(hf * L->inv_bottom_fade);
	R_ b = FN_(saturate)(((R_)1 - hf) * L->inv_top_fade);

	return a * a * ((R_)3 - (R_)2 * a) * (b * b * ((R_)3 - (R_)2 * b));
}

/* Extinction per km of layer L at field coordinates (x, y) km and
 * altitude h km: extinction_per_km times the envelope e, the coverage
 * (widened toward the top by anvil) times the profile, eroded by the
 * detail noise d: min(e, saturate((e - erosion d) / (1 - erosion))), which
 * removes wisps where e is thin and never adds to it; >= 0, 0 outside
 * [base, top]. */
static inline R_ FN_(density)(const struct FN_(layer) *L, R_ x, R_ y, R_ h, const R_ offset_km[2])
{
	R_ hf = (h - L->base_km) * L->inv_thickness_per_km;

	if (!(hf > (R_)0 && hf < (R_)1))
		return (R_)0;
	R_ px = FN_(wrap)(x - offset_km[0]), py = FN_(wrap)(y - offset_km[1]);
	R_ m = (FN_(coverage_fbm)(L, px, py) - L->threshold) * L->inv_edge;
	R_ c = FN_(saturate)(m + (R_)0.5 + L->anvil * hf * hf);
	R_ e = c * FN_(profile)(L, hf);
	if (!(e > (R_)0))
		return (R_)0;
	R_ d = FN_(detail)(L, px, py, FN_(wrap)(h));
	R_ f = FN_(saturate)((e - L->erosion * d) * L->inv_keep);
	return L->extinction_per_km * (f < e ? f : e);
}

/* The sum over n layers. */
static inline R_ FN_(density_all)(const struct FN_(layer) *layers, int n, R_ x, R_ y, R_ h,
				  const R_ offset_km[2])
{
	R_ sum = (R_)0;

	for (int i = 0; i < n; i++)
		sum += FN_(density)(&layers[i], x, y, h, offset_km);
	return sum;
}

/* The layers' occlusion of the sky seen from altitude h km, in [0, 1]:
 * 1 - prod_i (1 - cover_i (1 - exp(-tau_i))), tau_i the vertical optical
 * depth of layer i at full coverage above h (its profile integral, the
 * part above h taken as a linear share of the thickness). A regional
 * mean: the light from the whole sky, not the column overhead. */
static inline R_ FN_(sky_occlusion)(const struct FN_(layer) *layers, int n, R_ h)
{
	R_ open = (R_)1;

	for (int i = 0; i < n; i++) {
		const struct FN_(layer) *L = &layers[i];
		R_ above = FN_(saturate)((L->top_km - h) * L->inv_thickness_per_km);
		R_ tau = L->extinction_per_km * (L->top_km - L->base_km) * above * L->profile_integral;
		open *= (R_)1 - L->cover * ((R_)1 - SKYCLOUD_EXP(-tau));
	}
	return FN_(saturate)((R_)1 - open);
}

/* Altitude above a planet of radius rb_km of the point p (east, north, up
 * km from the ground point under the observer), as (|p - centre|^2 - rb^2)
 * / (|p - centre| + rb): exact where |p - centre| - rb cancels. */
static inline R_ FN_(altitude)(R_ rb_km, const R_ p[3])
{
	R_ rho2 = p[0] * p[0] + p[1] * p[1] + p[2] * ((R_)2 * rb_km + p[2]);
	R_ r = SKYCLOUD_SQRT(p[0] * p[0] + p[1] * p[1] + (rb_km + p[2]) * (rb_km + p[2]));

	return rho2 / (r + rb_km);
}

/* Distances along the ray o + t d (d unit) to the sphere of radius
 * rb + h_km about the centre (0, 0, -rb): the ray's span inside it
 * [*t0, *t1]; 0 when the ray misses it. */
static inline int FN_(sphere)(R_ rb_km, R_ h_km, const R_ o[3], const R_ d[3], R_ *t0, R_ *t1)
{
	R_ c[3] = { o[0], o[1], o[2] + rb_km };
	R_ b = c[0] * d[0] + c[1] * d[1] + c[2] * d[2];
	R_ r = rb_km + h_km;
	R_ cc = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) - r * r;
	R_ disc = b * b - cc;

	if (disc < (R_)0)
		return 0;
	R_ q = SKYCLOUD_SQRT(disc);
	*t0 = -b - q;
	*t1 = -b + q;
	return 1;
}

/* Optical depth of the layers along the ray from o (east, north, up km)
 * in the unit direction d, up to max_km, by the midpoint rule with steps
 * steps over the part of the ray between the lowest base and the highest
 * top (the shells follow the planet of radius rb_km). The light's cloud
 * transmittance at the observer is exp(-this) toward the light. */
static inline R_ FN_(optical_depth)(const struct FN_(layer) *layers, int n, const R_ offset_km[2],
				    R_ rb_km, const R_ o[3], const R_ d[3], R_ max_km, int steps)
{
	R_ lo = (R_)1e30, hi = (R_)-1e30;

	for (int i = 0; i < n; i++) {
		if (!(layers[i].cover > (R_)0))
			continue;
		lo = layers[i].base_km < lo ? layers[i].base_km : lo;
		hi = layers[i].top_km > hi ? layers[i].top_km : hi;
	}
	R_ a0, a1, b0, b1;
	if (!(hi > lo) || steps < 1 || !FN_(sphere)(rb_km, hi, o, d, &a0, &a1))
		return (R_)0;
	/* The span inside the top shell, less the part inside the base
	 * shell: the near piece (a ray that goes down through the layers
	 * and meets the base sphere stops there). */
	R_ t0 = a0 > (R_)0 ? a0 : (R_)0, t1 = a1 < max_km ? a1 : max_km;
	if (FN_(sphere)(rb_km, lo, o, d, &b0, &b1) && b1 > (R_)0) {
		if (b0 > t0)
			t1 = b0 < t1 ? b0 : t1;	/* above the base: down to it */
		else
			t0 = b1 > t0 ? b1 : t0;	/* below the base: up from it */
	}
	if (!(t1 > t0))
		return (R_)0;
	R_ dt = (t1 - t0) / (R_)steps, tau = (R_)0;
	for (int k = 0; k < steps; k++) {
		R_ t = t0 + ((R_)k + (R_)0.5) * dt;
		R_ p[3] = { o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2] };
		tau += FN_(density_all)(layers, n, p[0], p[1], FN_(altitude)(rb_km, p), offset_km);
	}
	return tau * dt;
}

#undef R_
#undef FN_
#undef SKYCLOUD_REAL
#undef SKYCLOUD_FN
#undef SKYCLOUD_FLOOR
#undef SKYCLOUD_SQRT
#undef SKYCLOUD_EXP
#endif /* SKYCLOUD_BODY */
