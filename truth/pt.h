/* pt.h - a volumetric Monte Carlo path tracer on the CPU: the ground truth
 * that the sky-view tables are measured against.
 *
 * It computes the sky radiance L(direction) seen by an observer at
 * altitude_km above the ground of a struct atmo: a spherical planet, a
 * spherical shell of atmosphere with any constituents and density profiles,
 * a Lambertian ground with a per-channel albedo and a sun of finite angular
 * radius (a uniform disk) of a given illuminance per channel at the top of the
 * atmosphere. All scattering orders, per RGB channel, in double precision.
 *
 * What L holds, to match the tables: the light scattered at least once
 * towards the observer by the atmosphere between the observer and the first
 * surface along the view ray. The sun's disk is not in it, and neither is
 * the ground's own radiance where a view ray hits the ground (PT_SKY);
 * PT_GROUND adds that ground radiance (for energy checks) and PT_SINGLE keeps
 * exactly the first scattering order. Radiance comes in the unit of the
 * illuminance divided by sr (lx in, cd/m2 out).
 *
 * Frames: the observer's local frame, x east, y north, z up; elevation above
 * the astronomical horizon, azimuth eastward from north, both in degrees.
 *
 * A scene (pt_render_scene) adds the cloud layers of proto/skycloud.h, in
 * double, as a heterogeneous medium (the type's extinction, albedo and
 * Henyey-Greenstein phase; ratio and delta tracking against a majorant per
 * layer), and a terrain height field of proto/skyterrain.h as an opaque
 * Lambertian surface of the ground's albedo: both on every shadow ray and
 * every path segment after the first vertex. The view ray itself is the
 * tables' (PT_VIEW_AIR: the air's light along it, clouds and terrain on it
 * left to the client that draws them) or a client's (PT_VIEW_ALL: what the
 * eye sees, clouds and terrain included). docs/truth.md, "Clouds and
 * terrain".
 *
 * Results do not depend on the number of threads: every sample draws from a
 * counter-based random stream keyed by (seed, direction, sample, channel)
 * and partial sums are merged in a fixed order.
 */
#ifndef SKYD_PT_H
#define SKYD_PT_H

#include <stddef.h>
#include <stdint.h>

#include "atmo.h"
#define SKYCLOUD_DOUBLE 1
#include "skycloud.h"
#define SKYTERRAIN_DOUBLE 1
#include "skyterrain.h"

enum pt_mode {
	PT_SKY = 0,		/* all orders, in-scattered light only (the tables) */
	PT_SINGLE = 1,		/* exactly the first scattering order, no ground light */
	PT_GROUND = 2,		/* PT_SKY plus the radiance of the ground a view ray hits */
};

struct pt_sun {
	double elevation_deg;
	double azimuth_deg;
	double angular_radius_deg;	/* > 0; the disk is uniform in radiance */
	double illuminance[3];		/* at the top of the atmosphere, normal incidence */
};

struct pt_dir {
	double elevation_deg;
	double azimuth_deg;
};

struct pt_options {
	enum pt_mode mode;
	double rel_error;	/* stop a direction once every channel's standard
				 * error is at most rel_error times its mean; 0: never */
	uint64_t min_samples;	/* per direction, before the error test applies */
	uint64_t max_samples;	/* per direction: the budget */
	uint32_t batch;		/* samples per direction between error tests */
	int threads;		/* 0: all online CPUs */
	uint64_t seed;
};

struct pt_result {
	double radiance[3];
	double std_error[3];	/* standard error of the mean, per channel */
	uint64_t samples;	/* paths traced per channel */
};

/* Defaults: PT_SKY, 1 % relative error, 4096 to 2^24 samples in batches of
 * 4096, all CPUs, seed 1. */
void pt_options_default(struct pt_options *ret);

/* Traces n directions until each reaches opt->rel_error or opt->max_samples.
 * ret holds n results. altitude_km below 0 is clamped to 0; an observer above
 * the shell sees it from outside. Returns 0, -EINVAL for an atmosphere that
 * atmo_validate refuses or bad arguments, -ENOMEM, or -errno from pthreads. */
int pt_render(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
	      const struct pt_dir *dirs, size_t n, const struct pt_options *opt,
	      struct pt_result *ret);

/* The deterministic single-scattering integral PT_SINGLE estimates: a
 * composite Gauss-Legendre quadrature along the view ray, with the optical
 * depths to the observer and to every point of the sun's disk integrated by
 * the same quadrature (breakpoints at the profiles' kinks, cells sized by
 * the change of altitude), and the disk by a product rule (Gauss in
 * 1 - cos, uniform in angle). Accurate to about 1e-6 relative while the sun's
 * disk is clear of the horizon at every point of the ray; a partly occluded
 * disk makes the disk rule converge slowly. Returns 0 or -EINVAL. */
int pt_single_scatter_reference(const struct atmo *a, double altitude_km,
				const struct pt_sun *sun, const struct pt_dir *dir,
				double ret_radiance[3]);

/* What the view ray sees of the clouds and the terrain. */
enum pt_view {
	PT_VIEW_AIR = 0,	/* the tables' view ray: the air's light, through air alone,
				 * to the sphere's ground or the top; clouds and terrain
				 * shadow it and scatter the light it gets */
	PT_VIEW_ALL = 1,	/* the eye's: the first vertex by delta tracking through
				 * air and clouds, the ray ends on the terrain too */
};

/* The media a scene adds to the air. */
struct pt_scene {
	int n_layers;					/* 0 .. SKYCLOUD_MAX_LAYERS */
	struct skycloudd_layer layers[SKYCLOUD_MAX_LAYERS];	/* skycloudd_layer_init's */
	double offset_km[2];				/* the wind's, east and north */
	const struct skyterrain *terrain;		/* NULL: none; the caller keeps its texels */
	enum pt_view view;
};

/* pt_render with the clouds and terrain of scene (NULL: none, as
 * pt_render). Returns pt_render's codes; -EINVAL for a scene with more than
 * SKYCLOUD_MAX_LAYERS layers or a view it does not know. */
int pt_render_scene(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		    const struct pt_scene *scene, const struct pt_dir *dirs, size_t n,
		    const struct pt_options *opt, struct pt_result *ret);

/* pt_single_scatter_reference with the scene's clouds and terrain on the
 * light's way (PT_VIEW_AIR: the air's single scattering along the tables'
 * view ray): the disk's cloud optical depth and terrain taken at its
 * centre (skycloudd_optical_depth, 256 steps; skyterraind_ray_hit), the
 * air's by the disk rule. Returns 0 or -EINVAL. */
int pt_single_scatter_scene(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
			    const struct pt_scene *scene, const struct pt_dir *dir,
			    double ret_radiance[3]);

/* How much of the air's single scattering along the tables' view ray the
 * scene's clouds and terrain shadow: 1 - L1(scene) / L1(clear) of
 * luminance (Rec. 709 weights), the sun's centre only, in [0, 1]; 0 where
 * the clear sky has none. The accuracy report's categories (lit, in
 * shadow, shafts) are cut from it. Returns 0 or -EINVAL. */
int pt_shadow_fraction(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		       const struct pt_scene *scene, const struct pt_dir *dir, double *ret_fraction);

/* The two sums pt_shadow_fraction compares, per channel: the air's single
 * scattering along the tables' view ray clear and under the scene (the
 * sun's centre only). Returns 0 or -EINVAL. */
int pt_shadow_pair(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		   const struct pt_scene *scene, const struct pt_dir *dir, double ret_clear[3],
		   double ret_shaded[3]);

/* What the sky tables assume, traced otherwise exactly, to measure what
 * each assumption costs against PT_SKY (skytruth --isotropic, --delta-m). */
struct pt_approx {
	int isotropic;		/* light scattered once already scatters isotropically
				 * at every later vertex (Hillaire's isotropic psi_ms);
				 * the light's first scattering keeps its phase */
	int delta_m;		/* 1 + the constituent whose phase is delta-M scaled for
				 * the orders >= 2 (pt_render.c: render_delta_m); 0 none */
	double delta_f;		/* its forward fraction f, in [0, 1) */
	double delta_g;		/* the scaled phase's g' (Henyey-Greenstein) */
	int delta_excess;	/* keep the peak-then-once-scattered light TMS drops */
};

/* pt_render (opt->mode PT_SKY only) under the approximations of ap.
 * Returns 0, -EINVAL, -ENOMEM or pt_render's errors. */
int pt_render_approx(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		     const struct pt_dir *dirs, size_t n, const struct pt_options *opt,
		     const struct pt_approx *ap, struct pt_result *ret);

#endif
