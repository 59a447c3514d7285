/* model.h - the double-precision CPU model of the engine's equations: the
 * test oracle.
 *
 * Same mappings (proto/skymap.h), same quadrature rules, same guards as the
 * shaders; the caller raises the step counts in the state it passes to make
 * it converge. Tables are RGBA doubles in the layout of eng.h.
 */
#ifndef SKYD_MODEL_H
#define SKYD_MODEL_H

#include <stdint.h>

#include "phase.h"
#include "state.h"

struct model_tables {
	double *t[STATE_N_TABLES];	/* RGBA per texel, NULL where not computed */
	uint32_t w[STATE_N_TABLES], h[STATE_N_TABLES], d[STATE_N_TABLES];
};

/* Computes the tables in mask and what they depend on, at the sizes and step
 * counts of s. Returns 0 or -ENOMEM; free with model_tables_finish. */
int model_compute(const struct sky_state *s, uint32_t mask, struct model_tables *ret);
void model_tables_finish(struct model_tables *m);
/* Sizes every table of s and allocates the ones in mask's closure, zeroed
 * (what model_compute fills; also for tables read back from the engine).
 * Returns 0 or -ENOMEM. */
int model_tables_new(const struct sky_state *s, uint32_t mask, struct model_tables *ret);

/* A copy of s with every step count multiplied by factor (the oracle's
 * "high step counts"); sky-view uses its maximum everywhere. */
void model_refine(const struct sky_state *s, uint32_t factor, struct sky_state *ret);

/* The escape 1 - f_ms per channel at altitude_km: the mean over the
 * multi-scattering table's direction quadrature of what leaves along each
 * direction or is absorbed (plus what the ground does not return), i.e. the
 * denominator of psi_ms = L2 / (1 - f_ms) as the table computes it.
 * Returns 0 or -ENOMEM. */
int model_multiscatter_escape(const struct sky_state *s, double altitude_km, double ret_escape[3]);

/* Optical depth per channel from altitude_km along cos-zenith mu to the top
 * of the atmosphere, by the transmittance pass's quadrature with steps steps
 * (the ground is not tested: the caller says whether the ray hits it). */
void model_optical_depth(const struct atmo *a, double altitude_km, double mu, uint32_t steps,
			 double ret_tau[3]);

#endif
