/* skyterrain.h - the terrain height field: its height at a point by
 * bilinear interpolation and where a ray first meets it; one definition
 * for skyd's shadow pass, the render clients and the path tracer. The
 * model, the file formats and the keys: docs/terrain.md.
 *
 * Header-only, no allocation, nothing of libc beyond <math.h> and
 * <stdint.h>. Included plainly it is the float build, skyterrain_*; with
 * SKYTERRAIN_DOUBLE defined (to 1) before the include it is the double
 * build, skyterraind_* (the path tracer's), and a file may include both.
 *
 * The field: width x height texels of 16 bits (0 .. 65535), row 0 the
 * northern edge, column 0 the western, over a square of side extent_km
 * centred on the ground point under the observer (the observer's site).
 * A texel's value v stands for the height v / 65535 x height_km above the
 * planet's sphere (the ground the atmosphere knows); a texel is a cell of
 * the square and its value holds at the cell's centre. Between centres the
 * height is bilinear; between the outermost centres and the square's edge
 * it is the edge texels' (clamped); outside the square there is no
 * terrain (height 0), so a field whose edges are not 0 ends in a cliff
 * there.
 *
 * Conventions as proto/skycloud.h: lengths in km, the observer's
 * east-north-up frame with the planet's centre at (0, 0, -rb_km) below the
 * ground point under the observer; a point's field coordinates are its
 * east and north km, its altitude is above the sphere there, so the
 * terrain follows the planet's curvature.
 */
#ifndef SKYD_SKYTERRAIN_COMMON_H
#define SKYD_SKYTERRAIN_COMMON_H

#include <math.h>
#include <stdint.h>

/* Bumped with any change to what these functions return for the same
 * arguments. */
#define SKYTERRAIN_VERSION 1

/* The largest field in texels a side: 4096 is the largest 2-D image every
 * Vulkan device must support (maxImageDimension2D), and 4096^2 texels of
 * 16 bits are 32 MiB, read and decoded in a bounded time. */
#define SKYTERRAIN_MAX_TEXELS 4096
#define SKYTERRAIN_WHITE 65535

/* A height field as the functions take it: a view of texels that the
 * caller owns and keeps for as long as the view is used. */
struct skyterrain {
	const uint16_t *texels;		/* width x height, row-major, north row first */
	uint32_t width, height;		/* 1 .. SKYTERRAIN_MAX_TEXELS each */
	uint16_t max_texel;		/* the largest texel (bounds the search of a ray) */
	double extent_km;		/* the square's side, > 0 */
	double height_km;		/* what 65535 stands for, >= 0 */
};

/* The texel at column i (west to east) and row j (north to south),
 * clamped into the field. */
static inline uint16_t skyterrain_texel(const struct skyterrain *t, int32_t i, int32_t j)
{
	i = i < 0 ? 0 : i >= (int32_t)t->width ? (int32_t)t->width - 1 : i;
	j = j < 0 ? 0 : j >= (int32_t)t->height ? (int32_t)t->height - 1 : j;
	return t->texels[(size_t)j * t->width + (size_t)i];
}

#endif /* SKYD_SKYTERRAIN_COMMON_H */

/* ---- one precision: float (skyterrain_*) or double (skyterraind_*) ---- */

#if defined(SKYTERRAIN_DOUBLE) && !defined(SKYD_SKYTERRAIN_D_H)
#define SKYD_SKYTERRAIN_D_H
#define SKYTERRAIN_REAL double
#define SKYTERRAIN_FN(name) skyterraind_##name
#define SKYTERRAIN_FLOOR floor
#define SKYTERRAIN_SQRT sqrt
#define SKYTERRAIN_BODY
#elif !defined(SKYTERRAIN_DOUBLE) && !defined(SKYD_SKYTERRAIN_F_H)
#define SKYD_SKYTERRAIN_F_H
#define SKYTERRAIN_REAL float
#define SKYTERRAIN_FN(name) skyterrain_##name
#define SKYTERRAIN_FLOOR floorf
#define SKYTERRAIN_SQRT sqrtf
#define SKYTERRAIN_BODY
#endif

#ifdef SKYTERRAIN_BODY
#undef SKYTERRAIN_BODY
#define R_ SKYTERRAIN_REAL
#define FN_(name) SKYTERRAIN_FN(name)

/* Height in km at field coordinates (x east, y north) km, and its
 * gradient (d/dx, d/dy; NULL: not wanted): bilinear between the texels'
 * centres, the edge texels' value out to the square's edge, 0 (and a
 * zero gradient) outside the square or without a field. */
static inline R_ FN_(height_grad_km)(const struct skyterrain *t, R_ x_km, R_ y_km, R_ ret_grad[2])
{
	if (ret_grad)
		ret_grad[0] = ret_grad[1] = (R_)0;
	if (!t || !t->texels || !(t->extent_km > 0.0))
		return (R_)0;
	R_ e = (R_)t->extent_km, half = (R_)0.5 * e;
	if (!(x_km >= -half && x_km <= half && y_km >= -half && y_km <= half))
		return (R_)0;
	R_ sx = (R_)t->width / e, sy = (R_)t->height / e;
	R_ u = (x_km + half) * sx - (R_)0.5, v = (half - y_km) * sy - (R_)0.5;
	R_ u0 = SKYTERRAIN_FLOOR(u), v0 = SKYTERRAIN_FLOOR(v);
	R_ fu = u - u0, fv = v - v0;
	int32_t i = (int32_t)u0, j = (int32_t)v0;
	/* Clamped past the outermost centres: the edge texel's value, flat. */
	int flat_u = i < 0 || i + 1 >= (int32_t)t->width;
	int flat_v = j < 0 || j + 1 >= (int32_t)t->height;
	R_ a = (R_)skyterrain_texel(t, i, j), b = (R_)skyterrain_texel(t, i + 1, j);
	R_ c = (R_)skyterrain_texel(t, i, j + 1), d = (R_)skyterrain_texel(t, i + 1, j + 1);
	R_ k = (R_)(t->height_km / SKYTERRAIN_WHITE);
	R_ top = a + fu * (b - a), bottom = c + fu * (d - c);
	if (ret_grad) {
		/* v grows southward: d/dy = -sy d/dv. */
		R_ du = (b - a) + fv * ((d - c) - (b - a));
		R_ dv = bottom - top;
		ret_grad[0] = flat_u ? (R_)0 : k * sx * du;
		ret_grad[1] = flat_v ? (R_)0 : -k * sy * dv;
	}
	return k * (top + fv * (bottom - top));
}

static inline R_ FN_(height_km)(const struct skyterrain *t, R_ x_km, R_ y_km)
{
	return FN_(height_grad_km)(t, x_km, y_km, (R_ *)0);
}

/* Altitude above the sphere of radius rb_km of the point p (east, north,
 * up km from the ground point under the observer), without cancellation
 * near the ground (proto/skycloud.h's formula). */
static inline R_ FN_(altitude_km)(R_ rb_km, const R_ p[3])
{
	R_ rho2 = p[0] * p[0] + p[1] * p[1] + p[2] * ((R_)2 * rb_km + p[2]);
	R_ r = SKYTERRAIN_SQRT(p[0] * p[0] + p[1] * p[1] + (rb_km + p[2]) * (rb_km + p[2]));

	return rho2 / (r + rb_km);
}

/* How far p is above the terrain (< 0: inside it). */
static inline R_ FN_(clearance_km)(const struct skyterrain *t, R_ rb_km, const R_ p[3])
{
	return FN_(altitude_km)(rb_km, p) - FN_(height_km)(t, p[0], p[1]);
}

/* [*ret_t0, *ret_t1] within [0, t_max]: the part of the ray o + s d that
 * can meet the terrain, inside the square's columns and below its highest
 * texel's sphere; 0 when there is none. */
static inline int FN_(ray_span)(const struct skyterrain *t, R_ rb_km, const R_ o[3], const R_ d[3],
				R_ t_max, R_ *ret_t0, R_ *ret_t1)
{
	R_ half = (R_)0.5 * (R_)t->extent_km, t0 = (R_)0, t1 = t_max;

	for (int a = 0; a < 2; a++) {
		if (d[a] == (R_)0) {
			if (o[a] < -half || o[a] > half)
				return 0;
			continue;
		}
		R_ p = (-half - o[a]) / d[a], q = (half - o[a]) / d[a];
		if (p > q) {
			R_ s = p;
			p = q;
			q = s;
		}
		t0 = p > t0 ? p : t0;
		t1 = q < t1 ? q : t1;
	}
	/* Below the highest texel: inside the sphere of radius rb + top. */
	R_ top = (R_)(t->height_km * t->max_texel / SKYTERRAIN_WHITE);
	R_ c[3] = { o[0], o[1], o[2] + rb_km };
	R_ b = c[0] * d[0] + c[1] * d[1] + c[2] * d[2];
	R_ r = rb_km + top;
	R_ disc = b * b - ((c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) - r * r);
	if (disc < (R_)0)
		return 0;
	R_ q = SKYTERRAIN_SQRT(disc);
	t0 = -b - q > t0 ? -b - q : t0;
	t1 = -b + q < t1 ? -b + q : t1;
	*ret_t0 = t0;
	*ret_t1 = t1;
	return t1 > t0;
}

/* Where the ray o + s d (d unit) first goes below the terrain, s in
 * [0, t_max]: 1 with *ret_t, or 0 when it never does (then *ret_t is
 * untouched). A ray that starts inside the terrain meets it at s = 0.
 * Marched in steps of a quarter of a texel across the ground (and of a
 * quarter of the highest texel up or down), the crossing then bisected to
 * 1e-6 of a step: a ridge narrower than a quarter of a texel that a ray
 * grazes can be missed, nothing wider. Costs up to about 6 x the field's
 * width in height evaluations, for a ray across the whole square. */
static inline int FN_(ray_hit)(const struct skyterrain *t, R_ rb_km, const R_ o[3], const R_ d[3],
			       R_ t_max, R_ *ret_t)
{
	R_ t0, t1;

	if (!t || !t->texels || !(t->extent_km > 0.0) || t->max_texel == 0 ||
	    !FN_(ray_span)(t, rb_km, o, d, t_max, &t0, &t1))
		return 0;
	uint32_t w = t->width > t->height ? t->width : t->height;
	R_ texel = (R_)t->extent_km / (R_)w;
	R_ top = (R_)(t->height_km * t->max_texel / SKYTERRAIN_WHITE);
	R_ dh = SKYTERRAIN_SQRT(d[0] * d[0] + d[1] * d[1]), dz = d[2] < (R_)0 ? -d[2] : d[2];
	R_ step = (R_)1e30;
	if (dh > (R_)0)
		step = (R_)0.25 * texel / dh;
	if (dz > (R_)0 && (R_)0.25 * top / dz < step)
		step = (R_)0.25 * top / dz;
	if (!(step < (R_)1e30))
		return 0;
	R_ p[3], prev_s = t0;
	for (int a = 0; a < 3; a++)
		p[a] = o[a] + t0 * d[a];
	if (FN_(clearance_km)(t, rb_km, p) <= (R_)0) {
		*ret_t = t0;
		return 1;
	}
	for (R_ s = t0 + step;; s += step) {
		R_ sc = s < t1 ? s : t1;
		for (int a = 0; a < 3; a++)
			p[a] = o[a] + sc * d[a];
		if (FN_(clearance_km)(t, rb_km, p) <= (R_)0) {
			R_ lo = prev_s, hi = sc;
			for (int k = 0; k < 20; k++) {
				R_ mid = (R_)0.5 * (lo + hi);
				for (int a = 0; a < 3; a++)
					p[a] = o[a] + mid * d[a];
				if (FN_(clearance_km)(t, rb_km, p) <= (R_)0)
					hi = mid;
				else
					lo = mid;
			}
			*ret_t = hi;
			return 1;
		}
		if (sc >= t1)
			return 0;
		prev_s = sc;
	}
}

#undef R_
#undef FN_
#undef SKYTERRAIN_REAL
#undef SKYTERRAIN_FN
#undef SKYTERRAIN_FLOOR
#undef SKYTERRAIN_SQRT
#endif /* SKYTERRAIN_BODY */
