/* pt_internal.h - what the path tracer's estimator (pt.c) and its driver
 * (pt_render.c) share: the medium, the random streams and the per-direction
 * view-ray tables. */
#ifndef SKYD_PT_INTERNAL_H
#define SKYD_PT_INTERNAL_H

#include <stdint.h>

#include "pt.h"

#define GROUPS 48		/* cells of the sunlit proposal per view ray */

struct medium {
	double rb, rt;
	int n;
	const struct atmo_constituent *c;
	double ext[ATMO_MAX_CONSTITUENTS][3];
	double majorant[3];
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

/* 0, or -EINVAL for an atmosphere atmo_validate refuses or a bad sun. */
int pt_check_args(const struct atmo *a, const struct pt_sun *sun);
/* The medium of a with the sun sun (isotropic and multi_only 0). */
void pt_medium_init(struct medium *m, const struct atmo *a, const struct pt_sun *sun);
/* The stream of one sample of one channel of one direction. */
void pt_rng_init(struct rng *r, uint64_t seed, uint64_t dir, uint64_t sample, int channel);
/* The view ray of dir from altitude_km and its optical-depth table.
 * Returns 0 or -ENOMEM; free with pt_view_free. */
int pt_view_build(struct view *v, const struct medium *m, double altitude_km, const struct pt_dir *dir);
void pt_view_free(struct view *v);
/* One sample of channel ch of the radiance along v, drawn from r. */
double pt_sample_view(const struct medium *m, const struct view *v, enum pt_mode mode, int ch, struct rng *r);

#endif
