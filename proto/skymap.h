/* skymap.h - the uv mappings of the published tables, shared by the daemon's
 * CPU model and libsky; proto/glsl/skymap.glsl is the same functions in
 * GLSL for skyd's shaders and render clients' (test_glsl_map checks the
 * pair).
 *
 * Header-only, double precision, no dependencies beyond <math.h>. A change
 * to any mapping here is made in skymap.glsl too and bumps SKYMAP_VERSION
 * (and SKYMAP_GLSL_VERSION), which is published in the shared memory header
 * and in manifest.json.
 *
 * Conventions: lengths in km, angles in radians. Texel (i, j) of a W x H
 * table holds the value at the texel centre; a texel's RGBA is at index
 * (j * W + i) * 4, rows bottom-up in v. The aerial perspective volume stacks
 * its slices: index ((k * H + j) * W + i) * 4.
 */
#ifndef SKYD_SKYMAP_H
#define SKYD_SKYMAP_H

#include <math.h>

/* Version 3: the multi-scattering table's A holds the share of the
 * ground's first bounce in psi_ms (luminance-weighted, in [0, 1]; it was the
 * mean f_ms), which the sky-view and aerial passes scatter through each
 * constituent's phase rather than isotropically (shaders/common.glsl,
 * ground_excess). */
#define SKYMAP_VERSION 4

#ifndef SKYMAP_PI
#define SKYMAP_PI 3.14159265358979323846
#endif

static inline double skymap_clamp(double x, double lo, double hi)
{
	return x < lo ? lo : x > hi ? hi : x;
}

static inline double skymap_safe_sqrt(double x)
{
	return sqrt(x > 0.0 ? x : 0.0);
}

/* Exact inverse pair: unit [0, 1] <-> texture coordinate whose ends are the
 * centres of the first and the last texel of n. */
static inline double skymap_unit_to_tex(double x, unsigned n)
{
	return 0.5 / n + x * (1.0 - 1.0 / n);
}

static inline double skymap_tex_to_unit(double u, unsigned n)
{
	return (u - 0.5 / n) / (1.0 - 1.0 / n);
}

/* rho^2 = r^2 - Rb^2 written as h (2 Rb + h): exact at small altitudes. */
static inline double skymap_rho2(double rb, double altitude_km)
{
	return altitude_km * (2.0 * rb + altitude_km);
}

/* Cosine of the zenith angle of the geometric horizon seen from altitude h;
 * -sqrt(h (2R + h)) / r, exact where -sqrt(1 - (R/r)^2) is not. */
static inline double skymap_horizon_cos(double rb, double altitude_km)
{
	double h = altitude_km > 0.0 ? altitude_km : 0.0;
	return -skymap_safe_sqrt(skymap_rho2(rb, h)) / (rb + h);
}

/* Distance from altitude h along cos-zenith mu to the sphere of radius
 * rb + shell (shell = rt - rb), for a point inside it; >= 0. */
static inline double skymap_distance_to_top(double rb, double rt, double altitude_km, double mu)
{
	double r = rb + altitude_km;
	double H2 = (rt - rb) * (rt + rb);
	double disc = r * r * mu * mu + H2 - skymap_rho2(rb, altitude_km);
	double d = -r * mu + skymap_safe_sqrt(disc);
	return d > 0.0 ? d : 0.0;
}

/* Transmittance table (Bruneton 2017): (altitude, mu) -> (u, v) in [0, 1],
 * for rays that do not hit the ground. */
static inline void skymap_transmittance_uv(double rb, double rt, double altitude_km, double mu,
					   unsigned w, unsigned h, double *ret_u, double *ret_v)
{
	double alt = skymap_clamp(altitude_km, 0.0, rt - rb);
	double H = skymap_safe_sqrt((rt - rb) * (rt + rb));
	double rho = skymap_safe_sqrt(skymap_rho2(rb, alt));
	double d = skymap_distance_to_top(rb, rt, alt, skymap_clamp(mu, -1.0, 1.0));
	double d_min = (rt - rb) - alt, d_max = rho + H;
	double x_mu = d_max > d_min ? (d - d_min) / (d_max - d_min) : 0.0;
	*ret_u = skymap_unit_to_tex(skymap_clamp(x_mu, 0.0, 1.0), w);
	*ret_v = skymap_unit_to_tex(skymap_clamp(rho / H, 0.0, 1.0), h);
}

/* The exact inverse: (u, v) -> (altitude, mu). */
static inline void skymap_transmittance_inverse(double rb, double rt, double u, double v,
						unsigned w, unsigned h, double *ret_altitude_km,
						double *ret_mu)
{
	double x_mu = skymap_tex_to_unit(u, w), x_r = skymap_tex_to_unit(v, h);
	double H = skymap_safe_sqrt((rt - rb) * (rt + rb));
	double rho = H * x_r;
	double r = sqrt(rho * rho + rb * rb);
	double alt = rho * rho / (r + rb);
	double d_min = (rt - rb) - alt, d_max = rho + H;
	double d = d_min + x_mu * (d_max - d_min);
	double mu = d <= 0.0 ? 1.0 : (H * H - rho * rho - d * d) / (2.0 * r * d);
	*ret_altitude_km = alt;
	*ret_mu = skymap_clamp(mu, -1.0, 1.0);
}

/* Multi-scattering table: v = altitude / shell; u packs texels around the
 * horizon of that altitude, where psi_ms falls by orders of magnitude within
 * a few degrees as the earth's shadow rises: with mu_h the horizon cosine at
 * the altitude and s = (mu_s - mu_h) / (1 + mu_h) below it, (mu_s - mu_h) /
 * (1 - mu_h) above it (both in [-1, 1]), u = 0.5 + 0.5 sign(s) sqrt(|s|).
 * A u linear in mu_s spends too few texels there and reads high in twilight
 * (docs/accuracy.md). */
static inline void skymap_multiscatter_uv(double rb, double rt, double altitude_km, double mu_s,
					  unsigned w, unsigned h, double *ret_u, double *ret_v)
{
	double alt = skymap_clamp(altitude_km, 0.0, rt - rb);
	double mh = skymap_horizon_cos(rb, alt), d = skymap_clamp(mu_s, -1.0, 1.0) - mh;
	double sn = skymap_clamp(d < 0.0 ? d / (1.0 + mh) : d / (1.0 - mh), -1.0, 1.0);
	*ret_u = skymap_unit_to_tex(0.5 + 0.5 * copysign(sqrt(fabs(sn)), sn), w);
	*ret_v = skymap_unit_to_tex(alt / (rt - rb), h);
}

static inline void skymap_multiscatter_inverse(double rb, double rt, double u, double v,
					       unsigned w, unsigned h, double *ret_altitude_km,
					       double *ret_mu_s)
{
	double alt = skymap_clamp(skymap_tex_to_unit(v, h), 0.0, 1.0) * (rt - rb);
	double a = 2.0 * skymap_tex_to_unit(u, w) - 1.0, sn = a * fabs(a);
	double mh = skymap_horizon_cos(rb, alt);
	*ret_mu_s = skymap_clamp(mh + sn * (sn < 0.0 ? 1.0 + mh : 1.0 - mh), -1.0, 1.0);
	*ret_altitude_km = alt;
}

/* Sky-view table: longitude is the absolute azimuth (eastward from north)
 * over the full circle, periodic, u = azimuth / 2 pi with texel i centred at
 * (i + 0.5) / W. Latitude packs texels near the horizon, whose zenith angle
 * theta_h comes from the observer's altitude:
 *   above: v = 0.5 (1 - sqrt(1 - theta / theta_h))
 *   below: v = 0.5 + 0.5 sqrt((theta - theta_h) / (pi - theta_h))
 * through the sub-texel pair in v. */
static inline void skymap_skyview_uv(double horizon_cos, double view_zenith_rad,
				     double azimuth_rad, unsigned h, double *ret_u,
				     double *ret_v)
{
	double th = acos(skymap_clamp(horizon_cos, -1.0, 1.0));
	double t = skymap_clamp(view_zenith_rad, 0.0, SKYMAP_PI), x;
	if (t < th)
		x = 0.5 * (1.0 - skymap_safe_sqrt(1.0 - t / th));
	else
		x = 0.5 + 0.5 * skymap_safe_sqrt((t - th) / (SKYMAP_PI - th));
	double a = azimuth_rad / (2.0 * SKYMAP_PI);
	*ret_u = a - floor(a);
	*ret_v = skymap_unit_to_tex(x, h);
}

static inline void skymap_skyview_inverse(double horizon_cos, double u, double v, unsigned h,
					  double *ret_view_zenith_rad, double *ret_azimuth_rad)
{
	double th = acos(skymap_clamp(horizon_cos, -1.0, 1.0));
	double x = skymap_clamp(skymap_tex_to_unit(v, h), 0.0, 1.0);
	if (x < 0.5) {
		double a = 1.0 - 2.0 * x;
		*ret_view_zenith_rad = th * (1.0 - a * a);
	} else {
		double a = 2.0 * x - 1.0;
		*ret_view_zenith_rad = th + (SKYMAP_PI - th) * a * a;
	}
	*ret_azimuth_rad = 2.0 * SKYMAP_PI * u;
}

/* Aerial perspective: slice k (0-based) of n holds the integral from the
 * camera to the far edge of the slice, at depth range * ((k + 1) / n)^p,
 * p = 2 for squared spacing, 1 for linear. Depth 0 is (L = 0, T = 1). */
static inline double skymap_aerial_depth_km(unsigned k, unsigned n, double range_km, int squared)
{
	double x = (double)(k + 1) / n;
	return range_km * (squared ? x * x : x);
}

/* Continuous slice coordinate w for a depth: w = -1 at depth 0, w = k at the
 * far edge of slice k. */
static inline double skymap_aerial_slice(double depth_km, unsigned n, double range_km, int squared)
{
	double x = skymap_clamp(depth_km / range_km, 0.0, 1.0);
	return (squared ? sqrt(x) : x) * n - 1.0;
}

/* A panorama of an eye point (struct sky_shm_panorama): the texture
 * coordinates of the direction (azimuth east of north, elevation), texel i
 * of n centred at (i + 0.5) / n. Columns are azimuth0 + i * step; with
 * full_circle the last repeats the first (azimuths wrap, so that a clamping
 * sampler interpolates across north), else the columns of an arc, where a
 * direction outside it takes the nearer end. Rows are spaced in x =
 * sign(e) sqrt(|e|), e the elevation above horizon_rad: fine toward the
 * horizon, where the ground cuts the rays short. */
static inline void skymap_panorama_uv(double azimuth0_rad, double azimuth_step_rad, double row0,
				      double row_step, double horizon_rad, unsigned width,
				      unsigned height, int full_circle, double azimuth_rad,
				      double elevation_rad, double *ret_u, double *ret_v)
{
	const double two_pi = 2.0 * SKYMAP_PI;
	double du = azimuth_rad - azimuth0_rad, f;
	du -= two_pi * floor(du / two_pi);
	if (full_circle) {
		f = skymap_clamp(du / azimuth_step_rad, 0.0, width - 1.0);
	} else {
		double span = azimuth_step_rad * (width - 1.0);
		if (du > span)		/* outside the arc: the nearer end */
			du = du - span < two_pi - du ? span : 0.0;
		f = skymap_clamp(du / azimuth_step_rad, 0.0, width - 1.0);
	}
	double e = elevation_rad - horizon_rad;
	double x = e < 0.0 ? -sqrt(-e) : sqrt(e);
	double g = skymap_clamp((x - row0) / row_step, 0.0, height - 1.0);
	*ret_u = (f + 0.5) / width;
	*ret_v = (g + 0.5) / height;
}

/* Ray-sphere: the distances at which a ray from altitude h with cos-zenith mu
 * crosses the sphere of radius rb + sphere_alt. Returns 0 when it misses. */
static inline int skymap_ray_sphere(double rb, double altitude_km, double mu, double sphere_alt_km,
				    double *ret_t0, double *ret_t1)
{
	double r = rb + altitude_km;
	/* r^2 mu^2 - (r^2 - R^2), with r^2 - R^2 = (h - a)(2 rb + h + a). */
	double c = (altitude_km - sphere_alt_km) * (2.0 * rb + altitude_km + sphere_alt_km);
	double disc = r * r * mu * mu - c;
	if (disc < 0.0)
		return 0;
	double s = sqrt(disc);
	*ret_t0 = -r * mu - s;
	*ret_t1 = -r * mu + s;
	return 1;
}

#endif
