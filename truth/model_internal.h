/* model_internal.h - what the files of the reference model share: its
 * vectors, its view of a state (struct ctx), the geometry and table reads
 * every pass uses, and each stage's entry points.
 *
 * model.c: the context, the tables, transmittance and the column densities;
 * model_light.c: the light at a point of a march (table lookups, sources);
 * model_delta.c: delta-M for the higher orders; model_ms.c: the
 * multi-scattering table and its iteration; model_sky.c: the sky-view and
 * aerial-perspective marches.
 */
#ifndef SKYD_MODEL_INTERNAL_H
#define SKYD_MODEL_INTERNAL_H

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "model.h"
#include "phase.h"
#include "skymap.h"

typedef struct {
	double x, y, z;
} v3;

static inline v3 v(double x, double y, double z) { return (v3){ x, y, z }; }
static inline v3 add(v3 a, v3 b) { return v(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline v3 mul(v3 a, v3 b) { return v(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline v3 scale(v3 a, double s) { return v(a.x * s, a.y * s, a.z * s); }
static inline v3 vexp_neg(v3 a) { return v(exp(-a.x), exp(-a.y), exp(-a.z)); }
static inline double dot(v3 a, v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline double mean3(v3 a) { return (a.x + a.y + a.z) / 3.0; }

/* The model's view of a state: what the shaders get as uniforms. */
struct ctx {
	const struct sky_state *s;
	const struct atmo *a;
	double rb, rt, shell, h0;
	v3 sun, moon, sun_illum, moon_illum;
	bool moon_lit;
	double night_cd_m2, night_gain;	/* state_night_floor */
	const struct model_tables *tab;
	/* phase_ground_fit of each constituent's phase_ground_excess (0 for one
	 * that scatters nothing) */
	double ground_fit[ATMO_MAX_CONSTITUENTS][PHASE_GROUND_FIT];
	/* The shape of the multiply scattered light for the constituent
	 * phase_moment_constituent names (-1 none): per multi-scattering
	 * texel the 4 numbers of multiscatter.comp's texel; that
	 * constituent's g1 and g2. */
	int lobe;
	double *moment;
	double lobe_g[2];
	/* Each constituent's scattering's weight in the lobe's (the lobe
	 * alone, or under a Rayleigh lobe every phase's g2 over the lobe's:
	 * forward_scattering in common.glsl). */
	double lobe_weight[ATMO_MAX_CONSTITUENTS];
	/* Delta-M (phase_delta_constituent, delta_source in common.glsl):
	 * the constituent (-1 none), its f and g', the scaled atmosphere
	 * (its scattering (1 - f) sigma_D through Henyey-Greenstein g'),
	 * its column density per transmittance texel (RGBA, in R), and
	 * whether the sunlight comes through the scaled transmittance (the
	 * multi-scattering table's context only). */
	int delta;
	double delta_f, delta_g, delta_h, delta_spread;
	struct atmo scaled;
	double *delta_col;
	bool delta_light;
};

struct medium {
	v3 scattering, absorption, extinction;
};

/* ---- geometry ---- */

static inline double rho2(const struct ctx *c, double h) { return h * (2.0 * c->rb + h); }

static inline double horizon_cos(const struct ctx *c, double h)
{
	return skymap_horizon_cos(c->rb, h);
}

/* (1 - exp(-sigma dt)) / sigma without cancellation; dt at sigma = 0. */
static inline double seg1(double sigma, double dt)
{
	double x = sigma * dt;
	if (x < 1e-4)
		return dt * (1.0 - x * (0.5 - x / 6.0));
	return -expm1(-x) / sigma;
}

static inline v3 segment_weight(v3 sigma, double dt)
{
	return v(seg1(sigma.x, dt), seg1(sigma.y, dt), seg1(sigma.z, dt));
}

/* The altitude at distance t from altitude h along cos-zenith mu, and the
 * radius there in ret_r. */
static inline double altitude_along(const struct ctx *c, double h, double mu, double t, double *ret_r)
{
	double r = c->rb + h;
	double excess = rho2(c, h) + t * (t + 2.0 * r * mu);
	*ret_r = sqrt(c->rb * c->rb + (excess > 0 ? excess : 0));
	return excess / (*ret_r + c->rb);
}

static inline double distance_to_top(const struct ctx *c, double h, double mu)
{
	return skymap_distance_to_top(c->rb, c->rt, h, mu);
}

/* Whether the ray from h along mu hits the ground, at distance ret_t. */
static inline bool hits_ground(const struct ctx *c, double h, double mu, double *ret_t)
{
	double mu_h = horizon_cos(c, h);
	*ret_t = 0.0;
	if (h < 0.0 || mu >= mu_h)
		return false;
	double r = c->rb + h;
	double disc = r * r * (mu - mu_h) * (mu + mu_h);
	double t = -r * mu - skymap_safe_sqrt(disc);
	*ret_t = t > 0 ? t : 0;
	return true;
}

static inline void put(double *dst, v3 rgb, double a)
{
	dst[0] = rgb.x;
	dst[1] = rgb.y;
	dst[2] = rgb.z;
	dst[3] = a;
}

/* ---- bilinear table reads ---- */

/* The four texels around (u, vv) of a w x h RGBA table (the edges clamped)
 * and the weights, as the shaders' bilinear reads. */
struct taps {
	size_t i00, i01, i10, i11;
	double fx, fy;
};

static inline struct taps taps_at(uint32_t w, uint32_t h, double u, double vv)
{
	double px = skymap_clamp(u, 0, 1) * w - 0.5, py = skymap_clamp(vv, 0, 1) * h - 0.5;
	int ix = (int)floor(px), iy = (int)floor(py);
	int x0 = ix < 0 ? 0 : ix > (int)w - 1 ? (int)w - 1 : ix;
	int x1 = ix + 1 < 0 ? 0 : ix + 1 > (int)w - 1 ? (int)w - 1 : ix + 1;
	int y0 = iy < 0 ? 0 : iy > (int)h - 1 ? (int)h - 1 : iy;
	int y1 = iy + 1 < 0 ? 0 : iy + 1 > (int)h - 1 ? (int)h - 1 : iy + 1;
	return (struct taps){ 4 * ((size_t)y0 * w + x0), 4 * ((size_t)y0 * w + x1),
			      4 * ((size_t)y1 * w + x0), 4 * ((size_t)y1 * w + x1),
			      px - floor(px), py - floor(py) };
}

static inline double taps_channel(const double *tab, const struct taps *t, int ch)
{
	double top = tab[t->i00 + ch] + (tab[t->i01 + ch] - tab[t->i00 + ch]) * t->fx;
	double bot = tab[t->i10 + ch] + (tab[t->i11 + ch] - tab[t->i10 + ch]) * t->fx;
	return top + (bot - top) * t->fy;
}

static inline v3 bilinear(const double *tab, uint32_t w, uint32_t h, double u, double vv)
{
	struct taps t = taps_at(w, h, u, vv);
	return v(taps_channel(tab, &t, 0), taps_channel(tab, &t, 1), taps_channel(tab, &t, 2));
}

/* bilinear() of the A channel. */
static inline double bilinear_a(const double *tab, uint32_t w, uint32_t h, double u, double vv)
{
	struct taps t = taps_at(w, h, u, vv);
	return taps_channel(tab, &t, 3);
}

/* ---- model.c: the context, transmittance and columns ---- */

/* The model's context for state s reading the tables in tab (delta-M and
 * the shape not set up). */
void model_ctx_init(struct ctx *c, const struct sky_state *s, const struct model_tables *tab);
/* The medium's coefficients at altitude h. */
struct medium model_medium(const struct ctx *c, double h);
/* The column density of profile p from altitude h along mu to the top, as
 * the transmittance pass computes it in steps steps. */
double model_column(const struct ctx *c, const struct atmo_profile *p, double h, double mu, uint32_t steps);
/* Optical depth per channel from altitude h along mu to the top. */
v3 model_depth_to_top(const struct ctx *c, double h, double mu, uint32_t steps);

/* ---- model_light.c: the light at a point of a march ---- */

v3 model_phased_scattering(const struct ctx *c, double h, double mu);
/* The transmittance table toward mu from h; 0 when the ray hits the ground. */
v3 model_transmittance_to_top(const struct ctx *c, double h, double mu);
double model_disk_visible_mean(double xa, double xb, double e);
double model_disk_halfwidth(const struct ctx *c, double h, double radius_rad);
double model_light_visible(const struct ctx *c, double h, double mu, double radius_rad);
v3 model_light_transmittance(const struct ctx *c, double h, double mu, double radius_rad);
v3 model_step_light(const struct ctx *c, double h, double mu_l, double radius_deg, double visible);
struct taps model_transmittance_taps(const struct ctx *c, double h, double mu);
/* psi_ms at h and mu_s, the ground's share in ret_share and the shape's 4
 * numbers in ret_shape. */
v3 model_multiscatter(const struct ctx *c, double h, double mu_s, double *ret_share, double ret_shape[4]);
v3 model_ground_scattering(const struct ctx *c, double h, double mu_view);
v3 model_higher_orders(const struct ctx *c, double h, v3 up, v3 dir, v3 light, v3 sigma_s, v3 ground, v3 fwd);
v3 model_light_source(const struct ctx *c, double h, v3 up, v3 dir, v3 light, double radius_deg,
		      double visible, v3 illum, v3 sigma_s, v3 ground);

/* ---- model_delta.c: delta-M ---- */

int model_delta_init(struct ctx *c, const struct sky_state *s, const struct model_tables *m);
v3 model_delta_light_transmittance(const struct ctx *c, double h, double mu, double radius_rad);
void model_delta_step(const struct ctx *c, double hs, v3 up, v3 dir, double dt, double vis_sun,
		      double vis_moon, struct medium m, v3 *radiance, v3 *tau, v3 *tau_scaled);

/* ---- model_ms.c and model_sky.c: the tables after transmittance ---- */

/* Fills out, the multi-scattering table of q with dirs directions (and
 * c->moment under a lobe constituent). Returns 0 or -ENOMEM. */
int model_compute_multiscatter(const struct ctx *c, const struct state_table_quality *q, uint32_t dirs,
			       double *out);
void model_compute_skyview(const struct ctx *c, const struct state_table_quality *q, double *out);
void model_compute_aerial(const struct ctx *c, const struct state_table_quality *q, double *out);

#endif
