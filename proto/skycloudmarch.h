/* skycloudmarch.h - drawing the cloud field on the CPU: the shadow of the
 * layers on a point from a Beer shadow map, a march of the layers along a
 * view ray lit from the sky's tables, and the compositing of clouds with
 * the sky and aerial perspective; proto/glsl/skycloud_march.glsl is the
 * same functions in GLSL (test_glsl_cloud_march checks the pair). The
 * model, its choices and its costs: docs/clouds.md, "Drawing clouds in a
 * client".
 *
 * Header-only, no allocation, thread-safe on memory that does not change
 * under it. The density is skycloud.h's float build (the device's bits);
 * the light and the march are in double, as skysample.h samples the sky's
 * tables (bilinear between texel centres, RGB times the table's scale).
 *
 * Conventions: skycloud.h's (km, the observer's east-north-up frame, the
 * planet's centre at (0, 0, -bottom_radius_km)); a light direction points
 * toward the light; the view ray o + t d has d unit.
 *
 * The cloud tables as skyd publishes them (layout 7, proto/skyproto.h;
 * docs/clouds.md, "Published"), taken here as plain tables (struct
 * skysample_table), so that a slot or an upload plugs in as it is:
 *   - the coverage table (SKY_TABLE_CLOUD): 2-D, channel k = the coverage
 *     (skycloud_coverage) of the layer of index k over the square
 *     [-extent, extent]^2 km around the observer (x east, y north), texel
 *     (i, j) of n centred at -extent + (i + 0.5) 2 extent / n
 *     (skycloud_table_uv);
 *   - a light's Beer shadow map (SKY_TABLE_SHADOW: slice 0 the sun's,
 *     slice 1 the moon's; the march takes a slice as a 2-D table):
 *     RGBA32F = (front depth km, mean extinction per km, max optical
 *     depth, opaque depth km of the terrain or 1e30; a texel whose ray
 *     meets no cloud is (0, 0, 0, terrain), so that the filter blends a
 *     cloud's edge into the clear), orthographic along the light; where a
 *     point p falls in it and its depth along the light are the affine
 *     rows the slot publishes (struct skycloud_shadow_frame,
 *     skycloud_shadow_frame_from_slot). The optical depth at depth dp is
 *     min(max_od, mean_ext max(0, dp - front)); beyond the terrain's depth
 *     the point is in the terrain's shadow.
 * The layers, their phase and albedo, the wind's offset and the region:
 * skycloud_scene_from_slot.
 */
#ifndef SKYD_SKYCLOUDMARCH_H
#define SKYD_SKYCLOUDMARCH_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "skycloud.h"
#include "skysample.h"

/* The quality knob: steps of a view march (docs/clouds.md gives their cost
 * on lavapipe). Light steps 0 read the shadow map; more march the field
 * toward the light instead, at that many steps per view step. */
#define SKYCLOUD_MARCH_STEPS_LOW 32
#define SKYCLOUD_MARCH_STEPS_MEDIUM 64
#define SKYCLOUD_MARCH_STEPS_HIGH 128
#define SKYCLOUD_MARCH_MAX_OCTAVES 4
/* A march stops once the view's transmittance is below this: what is left
 * behind adds at most this share of the light. */
#define SKYCLOUD_MARCH_MIN_TRANSMITTANCE 1e-3

/* The affine map of a light's shadow map: for a point p (ENU km),
 * u = row_u . (p, 1), v = row_v . (p, 1), its depth along the light from
 * the map's plane (growing away from the light) row_depth . (p, 1): the
 * slot's shadow_row_u, shadow_row_v, shadow_row_depth of the light.
 * terrain_bias_km: how far past the terrain's opaque depth a point must be
 * to be in the terrain's shadow (a ground point lies on it). */
struct skycloud_shadow_frame {
	double row_u[4], row_v[4], row_depth[4];
	double terrain_bias_km;
};

/* The layers and how they scatter: what a slot's layer parameters give. */
struct skycloud_scene {
	const struct skycloud_layer *layers;	/* n_layers of them, skycloud_layer_init's */
	int n_layers;				/* 0 .. SKYCLOUD_MAX_LAYERS */
	float offset_km[2];			/* the wind's offset (skycloud_wind_offset_km) */
	double phase_g[SKYCLOUD_MAX_LAYERS];	/* Henyey-Greenstein g per layer (the type's) */
	double albedo[SKYCLOUD_MAX_LAYERS];	/* single scattering per layer (the type's) */
	/* Multiple scattering (Wrenninge 2015, as Hillaire 2016): octave k
	 * scatters b^k of the light through extinction a^k toward the light
	 * and a phase of g c^k; 1 octave is single scattering. */
	int octaves;				/* 1 .. SKYCLOUD_MARCH_MAX_OCTAVES */
	double octave_a, octave_b, octave_c;	/* a <= b: energy is not gained */
	/* The coverage table and its half-width, or NULL: the field's own
	 * coverage (5 octaves of noise a step). */
	const struct skysample_table *coverage;
	double extent_km;
	/* The field's move since the coverage table was made (the slot's
	 * table_shift_km): field coordinates (x, y) read it at (x, y) - shift. */
	double table_shift_km[2];
	/* Sky irradiance on a horizontal surface, lx (sky_sample_ambient),
	 * scattered as isotropic skylight (E / pi): the first order of the
	 * sky's light, which the multi-scattering table leaves out; 0 for
	 * none. */
	double ambient_lx[3];
	/* 1: the light diffused through the layers (two-stream,
	 * skycloud_diffuse) in place of the octaves past the first; 0: the
	 * octaves alone. */
	int diffusion;
};

/* One light (the sun, or the moon when it lights). */
struct skycloud_light {
	double dir[3];				/* unit, toward the light */
	double illuminance_lx[3];		/* at the top of the atmosphere */
	const struct skysample_table *shadow;	/* its Beer shadow map; NULL: none */
	struct skycloud_shadow_frame frame;
};

/* The sky's tables the light comes through. */
struct skycloud_sky {
	const struct skysample_table *transmittance, *multiscatter;
	double bottom_radius_km, top_radius_km;
};

/* What a view march gives. */
struct skycloud_sample {
	double radiance[3];	/* in-scattered by the clouds toward the eye, cd/m2 */
	double transmittance;	/* of the clouds along the ray (grey) */
	double depth_km;	/* the clouds' mean distance, weighted by their opacity; the
				 * ray's far end when it meets none */
};

/* The scene's defaults for its layers: each type's phase g and albedo,
 * three octaves with a = b = c = 1/2, the field's own coverage, no
 * skylight beyond the multi-scattering table's. */
static inline void skycloud_scene_init(struct skycloud_scene *sc, const struct skycloud_layer *layers,
				       int n_layers, const float offset_km[2])
{
	*sc = (struct skycloud_scene){ .layers = layers, .n_layers = n_layers, .octaves = 3,
				       .octave_a = 0.5, .octave_b = 0.5, .octave_c = 0.5 };
	sc->offset_km[0] = offset_km[0];
	sc->offset_km[1] = offset_km[1];
	for (int i = 0; i < n_layers && i < SKYCLOUD_MAX_LAYERS; i++) {
		sc->phase_g[i] = skycloud_types[layers[i].type].phase_g;
		sc->albedo[i] = skycloud_types[layers[i].type].albedo;
	}
}

/* The published layer is struct skycloud_layer field for field, then its
 * phase and albedo (proto/skyproto.h). */
_Static_assert(offsetof(struct sky_shm_cloud_layer, phase_g) == sizeof(struct skycloud_layer) &&
		       sizeof(struct skycloud_layer) == 72,
	       "a published layer begins with struct skycloud_layer");

/* The scene of a slot's clouds: its layers copied into layers (the first
 * 72 bytes of each published one), their phase g and albedo, the wind's
 * offset and the region's half-width, skycloud_scene_init's octaves; the
 * coverage table is the caller's to set (NULL: the field's own coverage).
 * Returns the number of layers. */
static inline int skycloud_scene_from_slot(const struct sky_shm_clouds *c,
					   struct skycloud_layer layers[SKYCLOUD_MAX_LAYERS],
					   struct skycloud_scene *ret)
{
	int n = c->n_layers < SKYCLOUD_MAX_LAYERS ? (int)c->n_layers : SKYCLOUD_MAX_LAYERS;
	const float off[2] = { (float)c->offset_km[0], (float)c->offset_km[1] };
	for (int i = 0; i < n; i++)
		memcpy(&layers[i], &c->layers[i], sizeof(layers[i]));
	skycloud_scene_init(ret, layers, n, off);
	for (int i = 0; i < n; i++) {
		ret->phase_g[i] = c->layers[i].phase_g;
		ret->albedo[i] = c->layers[i].albedo;
	}
	ret->extent_km = c->extent_km;
	ret->table_shift_km[0] = c->table_shift_km[0];
	ret->table_shift_km[1] = c->table_shift_km[1];
	ret->diffusion = 1;
	return n;
}

/* The coverage table's texture coordinate of field coordinates (x, y) km
 * (before the wind's offset: the table is computed with it), less the
 * table's shift (struct skycloud_scene's table_shift_km). */
static inline void skycloud_table_uv(double extent_km, double x, double y, double ret_uv[2])
{
	ret_uv[0] = 0.5 + 0.5 * x / extent_km;
	ret_uv[1] = 0.5 + 0.5 * y / extent_km;
}

/* The box a light's map spans, as skyd computes it (daemon/engine/
 * eng_clouds.c calls this too): over [-extent_km, extent_km]^2 x
 * [bottom_km, top_km] (bottom_km: the curvature's drop at the region's
 * corners, -extent^2 / R), orthographic, u horizontal and across the light
 * (east where the light is at the zenith), v = u x light up the light's
 * vertical plane, u in [-u_half, u_half] and v in [v_lo, v_hi] holding the
 * box seen along the light, and the depth 0 on the plane 1 km beyond the
 * box's corner nearest the light (plane: its distance along the light). */
struct skycloud_shadow_box {
	double u[3], v[3];
	double u_half_km, v_lo_km, v_hi_km, plane_km;
};

static inline void skycloud_shadow_box_of(const double light[3], double extent_km, double bottom_km,
					  double top_km, struct skycloud_shadow_box *ret)
{
	const double *l = light;
	double *u = ret->u, *v = ret->v, e = extent_km;
	double n = sqrt(l[1] * l[1] + l[0] * l[0]);

	u[0] = n < 1e-6 ? 1.0 : l[1] / n;
	u[1] = n < 1e-6 ? 0.0 : -l[0] / n;
	u[2] = 0.0;
	v[0] = u[1] * l[2] - u[2] * l[1];
	v[1] = u[2] * l[0] - u[0] * l[2];
	v[2] = u[0] * l[1] - u[1] * l[0];
	ret->u_half_km = (fabs(u[0]) + fabs(u[1])) * e;
	double v_half = (fabs(v[0]) + fabs(v[1])) * e;
	ret->v_lo_km = -v_half + fmin(v[2] * bottom_km, v[2] * top_km);
	ret->v_hi_km = v_half + fmax(v[2] * bottom_km, v[2] * top_km);
	ret->plane_km = (fabs(l[0]) + fabs(l[1])) * e + fmax(l[2] * bottom_km, l[2] * top_km) + 1.0;
}

/* The frame skyd publishes for a light's map (the box above as the affine
 * rows a client applies), bias 0. For a client that makes its own map, and
 * for tests. */
static inline void skycloud_shadow_frame_init(const double light[3], double extent_km, double bottom_km,
					      double top_km, struct skycloud_shadow_frame *ret)
{
	struct skycloud_shadow_box b;

	skycloud_shadow_box_of(light, extent_km, bottom_km, top_km, &b);
	double su = 1.0 / (2.0 * b.u_half_km), sv = 1.0 / fmax(b.v_hi_km - b.v_lo_km, 1e-3);
	for (int k = 0; k < 3; k++) {
		ret->row_u[k] = b.u[k] * su;
		ret->row_v[k] = b.v[k] * sv;
		ret->row_depth[k] = -light[k];
	}
	ret->row_u[3] = b.u_half_km * su;
	ret->row_v[3] = -b.v_lo_km * sv;
	ret->row_depth[3] = b.plane_km;
	ret->terrain_bias_km = 0.0;
}

/* Light k's (0 the sun, 1 the moon) frame as the slot publishes it
 * (struct sky_shm_clouds), bias 0. */
static inline void skycloud_shadow_frame_from_slot(const struct sky_shm_clouds *c, int k,
						   struct skycloud_shadow_frame *ret)
{
	for (int i = 0; i < 4; i++) {
		ret->row_u[i] = c->shadow_row_u[k][i];
		ret->row_v[i] = c->shadow_row_v[k][i];
		ret->row_depth[i] = c->shadow_row_depth[k][i];
	}
	ret->terrain_bias_km = 0.0;
}

/* The point whose map coordinates are (u, v) at depth 0: a texel's ray
 * starts there and runs along -light. The inverse of the frame's rows for
 * a frame of skycloud_shadow_frame_init (orthonormal axes). */
static inline void skycloud_shadow_frame_origin(const struct skycloud_shadow_frame *f, double u, double v,
						double ret_p[3])
{
	double nu = 0.0, nv = 0.0;
	for (int k = 0; k < 3; k++) {
		nu += f->row_u[k] * f->row_u[k];
		nv += f->row_v[k] * f->row_v[k];
	}
	for (int k = 0; k < 3; k++)
		ret_p[k] = (u - f->row_u[3]) * f->row_u[k] / nu + (v - f->row_v[3]) * f->row_v[k] / nv -
			   f->row_depth[3] * f->row_depth[k];
}

static inline double skycloud_affine(const double row[4], const double p[3])
{
	return row[0] * p[0] + row[1] * p[1] + row[2] * p[2] + row[3];
}

/* The light's optical depth through the clouds at p from its shadow map,
 * SKYCLOUD_SHADOW_OPAQUE past the terrain's opaque depth plus the bias; 0
 * outside the map (the region holds every cloud there is). */
#define SKYCLOUD_SHADOW_OPAQUE 1e30
static inline double skycloud_shadow_depth(const struct skysample_table *map,
					   const struct skycloud_shadow_frame *f, const double p[3])
{
	double u = skycloud_affine(f->row_u, p), v = skycloud_affine(f->row_v, p);
	if (!(u >= 0.0 && u <= 1.0 && v >= 0.0 && v <= 1.0))
		return 0.0;
	double dp = skycloud_affine(f->row_depth, p), t[4];
	skysample_bilinear(map, u, v, 0, 0, t);
	if (dp > t[3] + f->terrain_bias_km)
		return SKYCLOUD_SHADOW_OPAQUE;
	double tau = t[1] * (dp > t[0] ? dp - t[0] : 0.0);
	return tau < t[2] ? tau : t[2];
}

/* The light's transmittance at p (a ground point, or any): exp of minus
 * skycloud_shadow_depth, 0 in the terrain's shadow. */
static inline double skycloud_shadow(const struct skysample_table *map, const struct skycloud_shadow_frame *f,
				     const double p[3])
{
	return exp(-skycloud_shadow_depth(map, f, p));
}

/* Where the ray o + t d meets the sphere of altitude h_km: 0 if it misses,
 * else 1 and the roots. The quadratic's constant as x^2 + y^2 + (z - h)
 * (z + h + 2 rb), and the smaller root from the larger (the stable form):
 * a float keeps each root to its own ulps at the planet's scale, where the
 * textbook form loses a metre. */
static inline int skycloud_march_sphere(double rb_km, double h_km, const double o[3], const double d[3],
					double *ret_t0, double *ret_t1)
{
	double b = o[0] * d[0] + o[1] * d[1] + (o[2] + rb_km) * d[2];
	double cc = o[0] * o[0] + o[1] * o[1] + (o[2] - h_km) * (o[2] + h_km + 2.0 * rb_km);
	double disc = b * b - cc;
	if (disc < 0.0)
		return 0;
	double q = b > 0.0 ? -(b + sqrt(disc)) : -b + sqrt(disc);
	double r = q != 0.0 ? cc / q : 0.0;
	*ret_t0 = q < r ? q : r;
	*ret_t1 = q < r ? r : q;
	return 1;
}

/* The part [*t0, *t1] of the ray o + t d, t in [0, max_km], between the
 * lowest base and the highest top of the layers with cover: the near piece,
 * as skycloud_optical_depth takes it (a ray down through the base stops
 * there), and never past the ground. 0 when the ray misses them. */
static inline int skycloud_march_span(const struct skycloud_layer *layers, int n, double rb_km, const double o[3],
				      const double d[3], double max_km, double *t0, double *t1)
{
	double lo = 1e30, hi = -1e30, a0, a1, b0, b1;
	for (int i = 0; i < n; i++) {
		if (!(layers[i].cover > 0.0f))
			continue;
		lo = layers[i].base_km < lo ? layers[i].base_km : lo;
		hi = layers[i].top_km > hi ? layers[i].top_km : hi;
	}
	if (!(hi > lo) || !skycloud_march_sphere(rb_km, hi, o, d, &a0, &a1))
		return 0;
	double s0 = a0 > 0.0 ? a0 : 0.0, s1 = a1 < max_km ? a1 : max_km;
	if (skycloud_march_sphere(rb_km, 0.0, o, d, &b0, &b1) && b1 > 0.0)
		s1 = b0 < s1 ? b0 : s1;	/* the ground stops it */
	if (skycloud_march_sphere(rb_km, lo, o, d, &b0, &b1) && b1 > 0.0) {
		if (b0 > s0)
			s1 = b0 < s1 ? b0 : s1;
		else
			s0 = b1 > s0 ? b1 : s0;
	}
	*t0 = s0;
	*t1 = s1;
	return s1 > s0;
}

/* Extinction per km of layer L at (x, y, h) whose coverage c0 (without the
 * anvil) comes from a table: skycloud_density with c0 for saturate(margin +
 * 1/2). The anvil widens it only where c0 > 0. */
static inline float skycloud_density_cov(const struct skycloud_layer *L, float c0, float x, float y, float h,
					 const float offset_km[2])
{
	float hf = (h - L->base_km) * L->inv_thickness_per_km;
	if (!(hf > 0.0f && hf < 1.0f) || !(c0 > 0.0f))
		return 0.0f;
	float c = skycloud_saturate(c0 + L->anvil * hf * hf);
	float e = c * skycloud_profile(L, hf);
	if (!(e > 0.0f))
		return 0.0f;
	float px = skycloud_wrap(x - offset_km[0]), py = skycloud_wrap(y - offset_km[1]);
	float dn = skycloud_detail(L, px, py, skycloud_wrap(h));
	float f = skycloud_saturate((e - L->erosion * dn) * L->inv_keep);
	return L->extinction_per_km * (f < e ? f : e);
}

/* Each layer's extinction per km at p (ENU km), altitude h_km; their sum. */
static inline double skycloud_march_density(const struct skycloud_scene *sc, const double p[3], double h_km,
					    double ret_sigma[SKYCLOUD_MAX_LAYERS])
{
	float x = (float)p[0], y = (float)p[1], h = (float)h_km;
	double cov[4] = { 0.0, 0.0, 0.0, 0.0 }, sum = 0.0;
	if (sc->coverage) {
		double uv[2];
		skycloud_table_uv(sc->extent_km, p[0] - sc->table_shift_km[0], p[1] - sc->table_shift_km[1], uv);
		if (uv[0] >= 0.0 && uv[0] <= 1.0 && uv[1] >= 0.0 && uv[1] <= 1.0)
			skysample_bilinear(sc->coverage, uv[0], uv[1], 0, 0, cov);
	}
	for (int i = 0; i < sc->n_layers; i++) {
		const struct skycloud_layer *L = &sc->layers[i];
		float s = sc->coverage ? skycloud_density_cov(L, (float)cov[L->index & 3], x, y, h, sc->offset_km)
				       : skycloud_density(L, x, y, h, sc->offset_km);
		ret_sigma[i] = s;
		sum += s;
	}
	return sum;
}

/* One texel of a light's Beer shadow map, as skyd's pass is to compute it
 * (its CPU twin, for tests and for a client that makes its own): the ray
 * from the frame's point (u, v) at depth 0 along -light, its span through
 * the layers (skycloud_march_span), steps samples
 * at the midpoints; front and back the ends of the samples with cloud,
 * mean extinction their optical depth over back - front. A ray without
 * cloud: (0, 0, 0); the terrain's channel is terrain_km (huge where none). */
static inline void skycloud_shadow_texel(const struct skycloud_scene *sc, double rb_km,
					 const struct skycloud_shadow_frame *f, const double light[3], double u,
					 double v, int steps, double terrain_km, float ret_rgba[4])
{
	double o[3], d[3] = { -light[0], -light[1], -light[2] }, t0, t1, sigma[SKYCLOUD_MAX_LAYERS];
	double front = 0.0, back = 0.0, tau = 0.0;
	skycloud_shadow_frame_origin(f, u, v, o);
	if (steps > 0 && skycloud_march_span(sc->layers, sc->n_layers, rb_km, o, d, 1e30, &t0, &t1)) {
		double dt = (t1 - t0) / steps;
		for (int k = 0; k < steps; k++) {
			double t = t0 + (k + 0.5) * dt;
			double p[3] = { o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2] };
			float pf[3] = { (float)p[0], (float)p[1], (float)p[2] };
			double s = skycloud_march_density(sc, p, skycloud_altitude((float)rb_km, pf), sigma);
			if (!(s > 0.0))
				continue;
			if (!(tau > 0.0))
				front = t - 0.5 * dt;
			back = t + 0.5 * dt;
			tau += s * dt;
		}
	}
	ret_rgba[0] = (float)front;
	ret_rgba[1] = tau > 0.0 ? (float)(tau / (back - front)) : 0.0f;
	ret_rgba[2] = (float)tau;
	ret_rgba[3] = (float)terrain_km;
}

/* Henyey-Greenstein's phase in 1/sr at the cosine mu between the light's
 * travel and the scattered light's. */
static inline double skycloud_hg(double g, double mu)
{
	double den = 1.0 + g * g - 2.0 * g * mu;
	return (1.0 - g * g) / (4.0 * SKYMAP_PI * den * sqrt(den));
}

/* The sunlight's (moonlight's) transmittance through the air to p at
 * altitude h_km with the light's cos-zenith mu there: 0 below the horizon. */
static inline void skycloud_air_transmittance(const struct skycloud_sky *sky, double h_km, double mu,
					      double ret_rgb[3])
{
	double u, v, px[4];
	if (mu < skymap_horizon_cos(sky->bottom_radius_km, h_km > 0.0 ? h_km : 0.0)) {
		ret_rgb[0] = ret_rgb[1] = ret_rgb[2] = 0.0;
		return;
	}
	skymap_transmittance_uv(sky->bottom_radius_km, sky->top_radius_km, h_km, mu, sky->transmittance->width,
				sky->transmittance->height, &u, &v);
	skysample_bilinear(sky->transmittance, u, v, 0, 0, px);
	for (int c = 0; c < 3; c++)
		ret_rgb[c] = px[c];
}

/* The layers' optical depth from p along the unit direction l: steps
 * samples at the midpoints of the ray's span through them
 * (skycloud_march_span, whose stable roots keep the span to a float's ulps
 * where skycloud_optical_depth's lose a metre), the density as the view
 * march takes it (the coverage table where the scene has one). */
static inline double skycloud_light_march(const struct skycloud_scene *sc, double rb_km, const double p[3],
					  const double l[3], int steps)
{
	double t0, t1, sigma[SKYCLOUD_MAX_LAYERS], tau = 0.0;
	if (steps < 1 || !skycloud_march_span(sc->layers, sc->n_layers, rb_km, p, l, 1e30, &t0, &t1))
		return 0.0;
	double dt = (t1 - t0) / steps;
	for (int k = 0; k < steps; k++) {
		double t = t0 + (k + 0.5) * dt;
		double q[3] = { p[0] + t * l[0], p[1] + t * l[1], p[2] + t * l[2] };
		float qf[3] = { (float)q[0], (float)q[1], (float)q[2] };
		tau += skycloud_march_density(sc, q, skycloud_altitude((float)rb_km, qf), sigma);
	}
	return tau * dt;
}

/* The light's optical depth through the clouds from p toward it, the
 * terrain's shadow folded in (SKYCLOUD_SHADOW_OPAQUE): the shadow map's,
 * or light_steps steps of skycloud_light_march. */
static inline double skycloud_light_depth(const struct skycloud_scene *sc, const struct skycloud_light *li,
					  double rb_km, const double p[3], int light_steps)
{
	if (light_steps > 0)
		return skycloud_light_march(sc, rb_km, p, li->dir, light_steps);
	return li->shadow ? skycloud_shadow_depth(li->shadow, &li->frame, p) : 0.0;
}

/* A slab of vertical optical depth tau and phase g, conservative, lit by a
 * beam at cosine mu0 > 0: the share of the beam it lets through, direct
 * and scattered (the Eddington two-stream solution, Shettle and Weinman
 * 1970): (2/3 + mu0 + (2/3 - mu0) e^(-tau / mu0)) / (4/3 + (1 - g) tau),
 * 1 at tau 0, falling as 1 / tau in a thick cloud. */
static inline double skycloud_slab_transmittance(double tau, double g, double mu0)
{
	return (2.0 / 3.0 + mu0 + (2.0 / 3.0 - mu0) * exp(-tau / mu0)) / (4.0 / 3.0 + (1.0 - g) * tau);
}

/* The same slab under a uniform sky: the beam's share over the hemisphere
 * weighted by 2 mu0, by two-point Gauss-Legendre in mu0 (4/3 over the
 * denominator in the thick limit, as the exact integral). */
static inline double skycloud_slab_diffuse(double tau, double g)
{
	const double m0 = 0.21132486540518713, m1 = 0.7886751345948129;
	return m0 * skycloud_slab_transmittance(tau, g, m0) + m1 * skycloud_slab_transmittance(tau, g, m1);
}

/* The light diffused inside layer L (phase g) at altitude h_km, per unit
 * of its scattering and of the light's illuminance through the air: the
 * point lies at vertical optical depth tau_z = tau mu_l below the layer's
 * sunlit top (tau: its optical depth toward the light at cosine mu_l),
 * which lets down the share Fd of the light that the slab above it
 * scatters (skycloud_slab_transmittance less the beam); the part of the
 * layer below it, of depth tau_b by its mean profile, sends back up the
 * share Fu that a conservative slab reflects of all that comes down. The
 * radiance toward the eye (mu_v: the view's cosine to the local up) is
 * Fd / pi from above and Fu / pi from below, mixed by the view. */
static inline double skycloud_diffuse(const struct skycloud_layer *L, double g, double h_km, double tau,
				      double mu_l, double mu_v)
{
	if (!(mu_l > 0.0) || !(tau < SKYCLOUD_SHADOW_OPAQUE))
		return 0.0;
	double tau_z = tau * mu_l, beam = exp(-tau / mu_l);
	double below = skymap_clamp((h_km - L->base_km) * L->inv_thickness_per_km, 0.0, 1.0);
	double tau_b = (double)L->extinction_per_km * (L->top_km - L->base_km) * below * L->profile_integral;
	double fd = skycloud_slab_transmittance(tau_z, g, mu_l) - beam;
	double fu = (1.0 - skycloud_slab_diffuse(tau_b, g)) * (fd + beam);
	return mu_l * (fd * (1.0 + mu_v) + fu * (1.0 - mu_v)) / (2.0 * SKYMAP_PI);
}

/* The source at p per unit of each layer's extinction, summed over layers
 * with their extinctions sigma: octaves of sunlight through the air and
 * the cloud (with the scene's diffusion: the first, and the light
 * diffused through the layer, skycloud_diffuse), and the ambient
 * (multi-scattering table and skylight) under the sky the layers leave
 * open. mu: view . light; mu_v: the view's cosine to the local up. */
static inline void skycloud_march_source(const struct skycloud_scene *sc, const struct skycloud_light *li,
					 const struct skycloud_sky *sky, const double p[3], double h_km,
					 const double sigma[SKYCLOUD_MAX_LAYERS], double mu, double mu_v,
					 int light_steps, double ret_rgb[3])
{
	double rb = sky->bottom_radius_km, c[3] = { p[0], p[1], p[2] + rb };
	double r = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
	double mu_l = (c[0] * li->dir[0] + c[1] * li->dir[1] + c[2] * li->dir[2]) / r;
	double tr[3], ms[4], u, v;
	skycloud_air_transmittance(sky, h_km, mu_l, tr);
	double tau = tr[0] + tr[1] + tr[2] > 0.0 ? skycloud_light_depth(sc, li, rb, p, light_steps) : 0.0;
	double direct = 0.0, scatter = 0.0;
	for (int i = 0; i < sc->n_layers; i++) {
		double s = sc->albedo[i] * sigma[i];
		if (!(s > 0.0))
			continue;
		double bk = 1.0, ak = 1.0, ck = 1.0, lobes = 0.0;
		for (int k = 0; k < (sc->diffusion ? 1 : sc->octaves); k++) {
			lobes += bk * exp(-ak * tau) * skycloud_hg(ck * sc->phase_g[i], mu);
			bk *= sc->octave_b;
			ak *= sc->octave_a;
			ck *= sc->octave_c;
		}
		if (sc->diffusion)
			lobes += skycloud_diffuse(&sc->layers[i], sc->phase_g[i], h_km, tau, mu_l, mu_v);
		direct += s * lobes;
		scatter += s;
	}
	skymap_multiscatter_uv(rb, sky->top_radius_km, h_km, mu_l, sky->multiscatter->width,
			       sky->multiscatter->height, &u, &v);
	skysample_bilinear(sky->multiscatter, u, v, 0, 0, ms);
	float hf = (float)h_km;
	double open = 1.0 - skycloud_sky_occlusion(sc->layers, sc->n_layers, hf);
	for (int k = 0; k < 3; k++)
		ret_rgb[k] = li->illuminance_lx[k] * (tr[k] * direct + scatter * open * ms[k]) +
			     scatter * open * sc->ambient_lx[k] / SKYMAP_PI;
}

/* The clouds seen along the view ray o + t d (d unit), t in [0, max_km]
 * (the scene's depth: terrain or infinity), lit by one light: steps steps
 * (SKYCLOUD_MARCH_STEPS_*) over the ray's span through the layers
 * (skycloud_march_span), sample k at t0 + (k + jitter) dt, jitter in
 * [0, 1) (1/2 the midpoint; a client may vary it per pixel and frame);
 * each step's extinction and source taken constant over it and integrated
 * exactly (Hillaire 2015): L += T S (1 - exp(-sigma dt)) / sigma, T *=
 * exp(-sigma dt). light_steps 0 reads the light's shadow map, more march
 * toward the light. A second light (the moon) is a second call, whose
 * radiance adds (its transmittance is the same). */
static inline void skycloud_march(const struct skycloud_scene *sc, const struct skycloud_light *li,
				  const struct skycloud_sky *sky, const double o[3], const double d[3], double max_km,
				  int steps, int light_steps, double jitter, struct skycloud_sample *ret)
{
	double t0, t1, wsum = 0.0, tsum = 0.0, T = 1.0, sigma[SKYCLOUD_MAX_LAYERS];
	*ret = (struct skycloud_sample){ { 0.0, 0.0, 0.0 }, 1.0, max_km };
	if (steps < 1 || !skycloud_march_span(sc->layers, sc->n_layers, sky->bottom_radius_km, o, d, max_km, &t0, &t1))
		return;
	double dt = (t1 - t0) / steps;
	double mu = d[0] * li->dir[0] + d[1] * li->dir[1] + d[2] * li->dir[2];
	for (int k = 0; k < steps && T > SKYCLOUD_MARCH_MIN_TRANSMITTANCE; k++) {
		double t = t0 + (k + jitter) * dt;
		double p[3] = { o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2] }, src[3];
		float pf[3] = { (float)p[0], (float)p[1], (float)p[2] };
		double h = skycloud_altitude((float)sky->bottom_radius_km, pf);
		double s = skycloud_march_density(sc, p, h, sigma);
		if (!(s > 0.0))
			continue;
		double up = (p[0] * d[0] + p[1] * d[1] + (p[2] + sky->bottom_radius_km) * d[2]) /
			    sqrt(p[0] * p[0] + p[1] * p[1] + (p[2] + sky->bottom_radius_km) * (p[2] + sky->bottom_radius_km));
		skycloud_march_source(sc, li, sky, p, h, sigma, mu, up, light_steps, src);
		double dT = exp(-s * dt), w = T * (1.0 - dT);
		for (int c = 0; c < 3; c++)
			ret->radiance[c] += w * src[c] / s;
		wsum += w;
		tsum += w * t;
		T *= dT;
	}
	ret->transmittance = T;
	if (wsum > 0.0)
		ret->depth_km = tsum / wsum;
}

/* The light on the ground at altitude h_km under the layers, as regional
 * means and shares of the clear sky's: ret[0] of the sky's irradiance (the
 * open share of each layer, 1 - cover, and its cover share through the
 * slab, skycloud_slab_diffuse), ret[1] of a light's horizontal irradiance
 * at cosine mu_l that the layers scatter down (through each layer's cover
 * share, skycloud_slab_transmittance less the beam exp(-tau / mu_l) that
 * the shadow map gives the point itself). Each layer's vertical optical
 * depth is skycloud_sky_occlusion's; the layers are conservative and the
 * light between the ground and the cloud base reflected once more is left
 * out. Under a clear sky 1 and 0. */
static inline void skycloud_ground_light(const struct skycloud_scene *sc, double h_km, double mu_l,
					 double ret[2])
{
	double sky = 1.0, through = 1.0, beam = 1.0;
	for (int i = 0; i < sc->n_layers; i++) {
		const struct skycloud_layer *L = &sc->layers[i];
		double above = skymap_clamp((L->top_km - h_km) * L->inv_thickness_per_km, 0.0, 1.0);
		double tau = (double)L->extinction_per_km * (L->top_km - L->base_km) * above * L->profile_integral;
		double c = L->cover;
		sky *= 1.0 - c + c * skycloud_slab_diffuse(tau, sc->phase_g[i]);
		if (mu_l > 0.0) {
			through *= 1.0 - c + c * skycloud_slab_transmittance(tau, sc->phase_g[i], mu_l);
			beam *= 1.0 - c + c * exp(-tau / mu_l);
		}
	}
	ret[0] = sky;
	ret[1] = mu_l > 0.0 ? through - beam : 0.0;
}

/* The radiance of a pixel whose clouds c lie in front of what is behind
 * them (behind: the sky with its disks, or a surface with its own aerial
 * perspective), with the air's aerial perspective at the clouds' depth
 * (air_rgb in-scattered, air_t its transmittance; sky_aerial at
 * c->depth_km): the sky behind dimmed by the clouds, the air in front of
 * them, which the clouds hide no more than the sky holds it, and the
 * clouds' light through that air:
 *     L = T_c behind + (1 - T_c) air + T_air L_c
 * (the sky table's radiance is the air in front plus the air's
 * transmittance times the rest, so the air in front is counted once). */
static inline void skycloud_composite(const double behind[3], const struct skycloud_sample *c,
				      const double air_rgb[3], double air_t, double ret_rgb[3])
{
	for (int k = 0; k < 3; k++)
		ret_rgb[k] = c->transmittance * behind[k] + (1.0 - c->transmittance) * air_rgb[k] +
			     air_t * c->radiance[k];
}

#endif /* SKYD_SKYCLOUDMARCH_H */
