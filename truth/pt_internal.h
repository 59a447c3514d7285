/* pt_internal.h - what the path tracer's files share: the medium (air,
 * clouds, terrain) and its transport primitives (pt_media.c), the random
 * streams and vectors, the per-direction view-ray tables and the estimator
 * (pt.c), the deterministic references (pt_ref.c) and the driver
 * (pt_render.c). */
#ifndef SKYD_PT_INTERNAL_H
#define SKYD_PT_INTERNAL_H

#include <math.h>
#include <stdint.h>

#include "pt.h"

#define PI 3.14159265358979323846
#define GROUPS 48		/* cells of the sunlit proposal per view ray */
#define MAX_BREAKS 64

/* What a point holds, per kind of matter: the air's constituents'
 * densities at [0, n), each cloud layer's extinction per km at
 * [CLOUD_SLOT(i)]. */
#define PT_MEDIA (ATMO_MAX_CONSTITUENTS + SKYCLOUD_MAX_LAYERS)
#define CLOUD_SLOT(i) (ATMO_MAX_CONSTITUENTS + (i))

struct medium {
	double rb, rt;
	int n;
	const struct atmo_constituent *c;
	double ext[ATMO_MAX_CONSTITUENTS][3];
	double majorant[3];	/* the air's */
	double albedo[3];
	double dh_max_km;	/* cell height cap from the smallest scale height */
	int n_kinks;
	double kink_km[4 * ATMO_MAX_CONSTITUENTS * 2 + 4];
	double sun[3];		/* unit vector towards the sun's centre */
	double sun_u[3], sun_v[3];
	double sun_one_minus_cos;
	double illuminance[3];
	int isotropic;		/* pt_approx.isotropic: orders after the first scatter uniformly */
	int multi_only;		/* the view ray's first vertex adds no single scattering */
	/* The scene: cloud layers (their majorant is their extinction per km,
	 * inside their shell), the terrain, the view. */
	int n_layers;
	struct skycloudd_layer layers[SKYCLOUD_MAX_LAYERS];
	double layer_albedo[SKYCLOUD_MAX_LAYERS], layer_g[SKYCLOUD_MAX_LAYERS];
	double offset_km[2];
	int has_terrain;
	struct skyterrain terrain;
	enum pt_view view;
};

struct rng {
	uint64_t key, ctr;
};

struct view {
	double o[3], d[3];
	double t0, t1;
	int ground;		/* the view ray ends on the ground */
	int n;			/* cells */
	double *t;		/* n + 1 cell ends */
	double *tau[3];		/* optical depth from t0 to t[k] */
	/* The sunlit proposal: GROUPS spans of cells, each weighted by
	 * sigma_s T T_sun at its middle, so that twilight samples the lit air. */
	int ng;
	double gt[GROUPS + 1];
	double gcdf[3][GROUPS + 1];
	int err;
};

/* ---- vectors and random numbers ---- */

static inline double dot(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void axpy(const double o[3], double t, const double d[3], double ret[3])
{
	for (int i = 0; i < 3; i++)
		ret[i] = o[i] + t * d[i];
}

static inline uint64_t pt_mix64(uint64_t z)
{
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

/* Uniform in [0, 1). */
static inline double rnd(struct rng *r)
{
	uint64_t x = pt_mix64(r->key + ++r->ctr * 0x9e3779b97f4a7c15ull);
	return (double)(x >> 11) * 0x1.0p-53;
}

/* Orthonormal u, v completing n (Duff et al. 2017). */
void pt_basis(const double n[3], double u[3], double v[3]);
/* The direction at cos_t from n and angle phi about it. */
void pt_from_local(const double n[3], double cos_t, double phi, double ret[3]);
void pt_direction(double elevation_deg, double azimuth_deg, double ret[3]);

/* ---- pt_media.c: the medium ---- */

/* 0, or -EINVAL for an atmosphere atmo_validate refuses or a bad sun. */
int pt_check_args(const struct atmo *a, const struct pt_sun *sun);
/* The medium of a with the sun sun (isotropic and multi_only 0, no scene). */
void pt_medium_init(struct medium *m, const struct atmo *a, const struct pt_sun *sun);
/* Adds scene (NULL: none) to m; -EINVAL for one it cannot take. */
int pt_medium_scene(struct medium *m, const struct pt_scene *scene);
/* The stream of one sample of one channel of one direction. */
void pt_rng_init(struct rng *r, uint64_t seed, uint64_t dir, uint64_t sample, int channel);

double pt_altitude(const struct medium *m, const double x[3]);
/* What x holds (PT_MEDIA slots; the clouds' only where there are layers). */
void pt_densities(const struct medium *m, const double x[3], double rho[]);
/* Extinction and scattering per km of channel ch of what rho holds. */
double pt_sigma_t(const struct medium *m, const double rho[], int ch);
double pt_sigma_s(const struct medium *m, const double rho[], int ch);

/* Distance from x (inside the shell) along d to where the ray leaves it;
 * *ret_ground says whether that is the sphere's ground. */
double pt_exit_distance(const struct medium *m, const double x[3], const double d[3], int *ret_ground);
/* The view ray's stretch inside the shell, [*t0, *t1]; 0 if it misses. */
int pt_view_segment(const struct medium *m, const double o[3], const double d[3], double *t0,
		    double *t1, int *ret_ground);

/* Quadrature cells along a ray (the air's): ends at the point closest to
 * the centre and at every kink altitude, short enough for 8-point
 * Gauss-Legendre to integrate the profiles to rounding. */
struct walk {
	const struct medium *m;
	const double *o, *d;
	double bp[MAX_BREAKS];
	int nbp, j;
	double t;
};
void pt_walk_init(struct walk *w, const struct medium *m, const double o[3], const double d[3],
		  double ta, double tb);
int pt_walk_next(struct walk *w, double *ret_a, double *ret_b);
/* The air's optical depth per channel of the cell [a, b] / the ray [ta, tb]. */
void pt_cell_tau(const struct medium *m, const double o[3], const double d[3], double a, double b,
		 double ret[3]);
void pt_ray_tau(const struct medium *m, const double o[3], const double d[3], double ta, double tb,
		double ret[3]);
extern const double pt_gl_x[4], pt_gl_w[4];

/* The terrain: where the ray from x along d first meets it within t_max
 * (1 with *ret_t), and its outward normal at a point on it. */
int pt_terrain_hit(const struct medium *m, const double x[3], const double d[3], double t_max,
		   double *ret_t);
void pt_terrain_normal(const struct medium *m, const double x[3], double ret_n[3]);
/* The clouds' optical depth from x along d up to t_max by the midpoint
 * rule in steps steps (skycloudd_optical_depth); 0 without layers. */
double pt_cloud_tau(const struct medium *m, const double x[3], const double d[3], double t_max,
		    int steps);

/* Ratio tracking: an unbiased estimate of the transmittance from x along
 * d to the edge of the shell; 0 when the ray meets the ground or the
 * terrain. */
double pt_transmittance(const struct medium *m, const double x[3], const double d[3], int ch,
			struct rng *r);

/* Delta tracking from x along d to the next real collision. */
enum pt_event { PT_ESCAPE = 0, PT_COLLIDE = 1, PT_SURFACE = 2 };
struct pt_hit {
	double p[3];		/* where */
	double rho[PT_MEDIA];	/* PT_COLLIDE: what is there */
	double sigma_t;		/* PT_COLLIDE: its extinction */
	double normal[3];	/* PT_SURFACE: the ground's or the terrain's */
};
enum pt_event pt_fly(const struct medium *m, const double x[3], const double d[3], int ch,
		     struct rng *r, struct pt_hit *ret);

/* ---- pt.c: the estimator ---- */

/* The phase function of air constituent c, per steradian. */
double pt_phase(const struct atmo_constituent *c, double mu);
/* The phase mixture of what rho holds (sum sigma_s,i p_i / sigma_s). */
double pt_phase_mix(const struct medium *m, const double rho[], double sigma_s, double mu, int ch);
/* The view ray of dir from altitude_km and its optical-depth table.
 * Returns 0 or -ENOMEM; free with pt_view_free. */
int pt_view_build(struct view *v, const struct medium *m, double altitude_km, const struct pt_dir *dir);
void pt_view_free(struct view *v);
/* One sample of channel ch of the radiance along v, drawn from r. */
double pt_sample_view(const struct medium *m, const struct view *v, enum pt_mode mode, int ch, struct rng *r);

#endif
