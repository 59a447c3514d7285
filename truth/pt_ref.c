/* pt_ref.c - the path tracer's deterministic references: the air's single
 * scattering along a view ray by quadrature (pt.h), clear or under the
 * scene's clouds and terrain, and from the two the share of it that the
 * scene shadows (the accuracy report's categories). */
#include "pt_internal.h"

#include <errno.h>
#include <math.h>
#include <string.h>

/* 4-point Gauss-Legendre on [0, 1] for the disk's 1 - cos. */
static const double gl4_x[4] = { 0.0694318442029737, 0.3300094782075719,
				 0.6699905217924281, 0.9305681557970263 };
static const double gl4_w[4] = { 0.1739274225687269, 0.3260725774312731,
				 0.3260725774312731, 0.1739274225687269 };
#define DISK_PHI 8

/* Steps of the clouds' optical depth toward the sun: the reference's,
 * and the shadow fraction's (a category, not a value). */
#define REF_CLOUD_STEPS 256
#define FRACTION_CLOUD_STEPS 128

/* E * sum_i sigma_s,i rho_i p_i(w.d) T(x, w) of the air for one direction
 * w toward the sun, weighted by weight, added to ret. */
static void ss_ray(const struct medium *m, const double x[3], const double d[3], const double rho[],
		   const double w[3], double weight, double ret[3])
{
	int ground;
	double te = pt_exit_distance(m, x, w, &ground), tau[3];

	if (ground)
		return;
	pt_ray_tau(m, x, w, 0.0, te, tau);
	double mu = dot(w, d);
	for (int ch = 0; ch < 3; ch++) {
		double s = 0.0;
		for (int i = 0; i < m->n; i++)
			s += m->c[i].scattering_per_km[ch] * rho[i] * pt_phase(&m->c[i], mu);
		ret[ch] += weight * m->illuminance[ch] * s * exp(-tau[ch]);
	}
}

/* The air's source at x toward -d: over the sun's disk by the product rule
 * (disk), or from its centre alone. */
static void ss_source(const struct medium *m, const double x[3], const double d[3],
		      const double rho[], int disk, double ret[3])
{
	ret[0] = ret[1] = ret[2] = 0.0;
	if (!disk) {
		ss_ray(m, x, d, rho, m->sun, 1.0, ret);
		return;
	}
	for (int a = 0; a < 4; a++) {
		double v = gl4_x[a] * m->sun_one_minus_cos, cos_t = 1.0 - v;
		double sin_t = sqrt(fmax(0.0, v * (2.0 - v)));
		for (int b = 0; b < DISK_PHI; b++) {
			double phi = 2.0 * PI * (b + 0.5) / DISK_PHI, w[3];
			for (int i = 0; i < 3; i++)
				w[i] = cos_t * m->sun[i] +
				       sin_t * (cos(phi) * m->sun_u[i] + sin(phi) * m->sun_v[i]);
			ss_ray(m, x, d, rho, w, gl4_w[a] / DISK_PHI, ret);
		}
	}
}

/* What the scene leaves of the sun's light at x: 0 behind terrain, the
 * clouds' transmittance toward the disk's centre. */
static double scene_shade(const struct medium *m, const double x[3], int steps)
{
	int ground;
	double te = pt_exit_distance(m, x, m->sun, &ground), th;

	if (ground || pt_terrain_hit(m, x, m->sun, te, &th))
		return 0.0;
	return m->n_layers ? exp(-pt_cloud_tau(m, x, m->sun, te, steps)) : 1.0;
}

/* The highest point of the scene's casters: above it no cell is cut. */
static double scene_top_km(const struct medium *m)
{
	double top = -INFINITY;

	for (int i = 0; i < m->n_layers; i++)
		if (m->layers[i].cover > 0.0)
			top = fmax(top, m->layers[i].top_km);
	if (m->has_terrain)
		top = fmax(top, m->terrain.height_km * m->terrain.max_texel / SKYTERRAIN_WHITE);
	return top;
}

/* One cell [ca, cb] of the view ray: clear and shaded sums, and the
 * optical depth to its start in tau_a (advanced to its end). */
static void ss_cell(const struct medium *m, const double o[3], const double d[3], double ca,
		    double cb, int disk, int steps, double tau_a[3], double clear[3], double scene[3])
{
	double mid = 0.5 * (ca + cb), half = 0.5 * (cb - ca), c[3];

	for (int k = 0; k < 8; k++) {
		double t = mid + (k < 4 ? -pt_gl_x[k] : pt_gl_x[k - 4]) * half;
		double part[3], x[3], rho[PT_MEDIA], s[3];
		pt_cell_tau(m, o, d, ca, t, part);
		axpy(o, t, d, x);
		for (int i = 0; i < m->n; i++)
			rho[i] = atmo_density(&m->c[i].density, pt_altitude(m, x));
		ss_source(m, x, d, rho, disk, s);
		double shade = m->n_layers || m->has_terrain ? scene_shade(m, x, steps) : 1.0;
		for (int ch = 0; ch < 3; ch++) {
			double v = pt_gl_w[k & 3] * half * exp(-(tau_a[ch] + part[ch])) * s[ch];
			clear[ch] += v;
			scene[ch] += v * shade;
		}
	}
	pt_cell_tau(m, o, d, ca, cb, c);
	for (int ch = 0; ch < 3; ch++)
		tau_a[ch] += c[ch];
}

/* Cells reaching below the scene's top are cut to this length: the edges
 * of shadows are steps that one Gauss-Legendre cell would smear. */
#define SHADOW_CELL_KM 0.05
#define SHADOW_CELLS_MAX 400

/* The air's single scattering along the tables' view ray from altitude_km
 * toward dir, by composite Gauss-Legendre on the cells of pt_walk: clear in
 * ret_clear, shaded by the scene in ret_scene. */
static void ss_integrate(const struct medium *m, double altitude_km, const struct pt_dir *dir,
			 int disk, int steps, double ret_clear[3], double ret_scene[3])
{
	double o[3] = { 0 }, d[3], t0, t1, top = scene_top_km(m);
	int ground;

	for (int ch = 0; ch < 3; ch++)
		ret_clear[ch] = ret_scene[ch] = 0.0;
	o[2] = m->rb + (altitude_km > 0.0 ? altitude_km : 0.0);
	pt_direction(dir->elevation_deg, dir->azimuth_deg, d);
	if (!pt_view_segment(m, o, d, &t0, &t1, &ground) || !(t1 > t0))
		return;
	struct walk w;
	double ca, cb, tau_a[3] = { 0 }, xa[3], xb[3];
	pt_walk_init(&w, m, o, d, t0, t1);
	while (pt_walk_next(&w, &ca, &cb)) {
		axpy(o, ca, d, xa);
		axpy(o, cb, d, xb);
		int cuts = 1;
		if (fmin(pt_altitude(m, xa), pt_altitude(m, xb)) < top)
			cuts = (int)fmin(ceil((cb - ca) / SHADOW_CELL_KM), SHADOW_CELLS_MAX);
		for (int k = 0; k < cuts; k++)
			ss_cell(m, o, d, ca + (cb - ca) * k / cuts, ca + (cb - ca) * (k + 1) / cuts, disk,
				steps, tau_a, ret_clear, ret_scene);
	}
}

/* The medium of a, sun and scene; 0 or -EINVAL. */
static int ref_medium(struct medium *m, const struct atmo *a, double altitude_km,
		      const struct pt_sun *sun, const struct pt_scene *scene, const struct pt_dir *dir)
{
	if (pt_check_args(a, sun) < 0 || !dir || !isfinite(altitude_km))
		return -EINVAL;
	pt_medium_init(m, a, sun);
	return pt_medium_scene(m, scene);
}

int pt_single_scatter_reference(const struct atmo *a, double altitude_km,
				const struct pt_sun *sun, const struct pt_dir *dir,
				double ret_radiance[3])
{
	return pt_single_scatter_scene(a, altitude_km, sun, NULL, dir, ret_radiance);
}

int pt_single_scatter_scene(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
			    const struct pt_scene *scene, const struct pt_dir *dir,
			    double ret_radiance[3])
{
	struct medium m;
	double clear[3];

	if (!ret_radiance || ref_medium(&m, a, altitude_km, sun, scene, dir) < 0)
		return -EINVAL;
	ss_integrate(&m, altitude_km, dir, 1, REF_CLOUD_STEPS, clear, ret_radiance);
	return 0;
}

int pt_shadow_pair(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		   const struct pt_scene *scene, const struct pt_dir *dir, double ret_clear[3],
		   double ret_shaded[3])
{
	struct medium m;

	if (!ret_clear || !ret_shaded || ref_medium(&m, a, altitude_km, sun, scene, dir) < 0)
		return -EINVAL;
	ss_integrate(&m, altitude_km, dir, 0, FRACTION_CLOUD_STEPS, ret_clear, ret_shaded);
	return 0;
}

int pt_shadow_fraction(const struct atmo *a, double altitude_km, const struct pt_sun *sun,
		       const struct pt_scene *scene, const struct pt_dir *dir, double *ret_fraction)
{
	static const double y[3] = { 0.2126, 0.7152, 0.0722 };
	double clear[3], shaded[3], yc = 0.0, ys = 0.0;

	if (!ret_fraction || pt_shadow_pair(a, altitude_km, sun, scene, dir, clear, shaded) < 0)
		return -EINVAL;
	for (int ch = 0; ch < 3; ch++) {
		yc += y[ch] * clear[ch];
		ys += y[ch] * shaded[ch];
	}
	*ret_fraction = yc > 0.0 ? fmin(fmax(1.0 - ys / yc, 0.0), 1.0) : 0.0;
	return 0;
}
