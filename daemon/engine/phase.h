/* phase.h - the phase functions' properties that the engine uploads and the
 * reference model mirrors. */
#ifndef SKYD_PHASE_H
#define SKYD_PHASE_H

#include "state.h"

/* A constituent's phase function, normalised to 1 over the sphere, at the
 * scattering cosine mu. */
double phase_value(enum atmo_phase kind, double g, double mu);

/* The ground's first bounce seen through a constituent's phase. Sunlight
 * that the ground reflects reaches a point x from below; the
 * multi-scattering table carries it as an isotropic part of psi_ms (its
 * share in A), but scattered toward a viewer looking along cos-zenith mu_view
 * it goes through the phase at the angle between upwelling light and -view:
 * backwards for a viewer looking up, forwards for one looking down. With the
 * ground light taken uniform over the lower hemisphere, the phase's integral
 * over that hemisphere relative to the isotropic one is
 *   k(mu_view) = 2 * integral over upward d of p(-d . view),
 * 1 for the isotropic phase and (exactly) for Rayleigh's, 0.07 for
 * Cornette-Shanks g = 0.8 looking at the zenith and 1.92 at the nadir, and
 * k(-mu) = 2 - k(mu). ret_excess[i] = k(mu) - 1 at mu = i / (PHASE_GROUND_N - 1),
 * i.e. for viewers looking up; lookups interpolate linearly in |mu| and take
 * the sign of mu (see ground_excess in common.glsl). Costs about 30000 phase
 * evaluations: callers keep the result while the constituent stays. */
#define PHASE_GROUND_N 32
void phase_ground_excess(enum atmo_phase kind, double g, double ret_excess[PHASE_GROUND_N]);

/* What the marches evaluate instead of the table: a least-squares fit of
 * k - 1 over the table's mu by sum_{j=2..PHASE_GROUND_FIT+1} c_j s^j with
 * s = sqrt(|mu|), odd in mu like the table: a table lookup with a different
 * index in every lane is slow on lavapipe, the polynomial is a few
 * multiply-adds. Between the table's points it is
 * closer to the exact k than the table's linear interpolation: within
 * 1.4e-3 for Cornette-Shanks g = 0.8 and 5.3e-3 for Henyey-Greenstein
 * g = 0.95 (test_ground). ret_coef[j] multiplies s^(j + 2). */
#define PHASE_GROUND_FIT 8
void phase_ground_fit(const double excess[PHASE_GROUND_N], double ret_coef[PHASE_GROUND_FIT]);
/* The fit at mu_view, in Horner form as ground_excess() in common.glsl. */
double phase_ground_fit_at(const double coef[PHASE_GROUND_FIT], double mu_view);

/* The Legendre moment g_l of a phase function normalised to 1 over the
 * sphere (the mean of P_l of the scattering cosine; g_1 is the mean cosine):
 * g^l for Henyey-Greenstein, by quadrature otherwise (Cornette-Shanks:
 * g_1 = 3 g (4 + g^2) / (5 (2 + g^2)); Rayleigh: g_1 = 0, g_2 = 0.1);
 * 0 for none. */
double phase_legendre(enum atmo_phase kind, double g, int l);

/* The constituent (its index in s->atmo) whose phase scatters the lobe of
 * the multiply scattered light (ms_source in shaders/common.glsl), or -1
 * for none: the one of largest |g1| times vertical scattering optical
 * depth (green); none with fewer than 64 multi-scattering directions
 * (up and down see no shape); multiscatter_moment=off: none; on: that one; auto: that
 * one where its |g1| tau reaches 0.02, i.e. where a forward-peaked phase
 * steers a share of the light that matters (Mars' dust: 0.15; Earth's thin
 * Mie layer: 0.004). g1_of: phase_legendre(..., 1) of each
 * constituent of s->atmo if the caller keeps it, else NULL. */
int phase_moment_constituent(const struct sky_state *s, const double *g1_of);

/* Delta-M for the multiply scattered light (multiscatter_delta): the
 * constituent whose forward peak the higher orders treat as no scattering
 * at all, or -1. auto: the one phase_moment_constituent picks under
 * multiscatter_moment=auto (Mars' dust, not Earth's Mie); on: the one it
 * picks under on; off: none; none where the neighbourhood iteration runs
 * (state_multiscatter_iterations); never a constituent whose mean cosine is not
 * positive (no forward peak). Where it is on, the shape of
 * multiscatter_moment is the scaled medium's (phase_lobe_constituent). */
int phase_delta_constituent(const struct sky_state *s, const double *g1_of);

/* The constituent whose phase scatters the shape of the multiply scattered
 * light, as the engine applies the knobs: phase_moment_constituent; where
 * delta-M is on, the scaled medium's shape through the truncated phase, of
 * the same constituent only (-1 otherwise or under multiscatter_moment=off).
 * Where multiscatter_moment=auto finds no forward lobe (Earth), the Rayleigh
 * constituent: a lobe of g1 = 0 that carries the field's band 2 alone, to
 * every constituent's phase (ms_source in shaders/common.glsl). */
int phase_lobe_constituent(const struct sky_state *s, const double *g1_of);

/* The delta-M truncation of a phase: the forward fraction f (the phase's
 * Legendre moment of order PHASE_DELTA_ORDER) and the Henyey-Greenstein
 * parameter g' = (g1 - f) / (1 - f) of what is left. Cornette-Shanks
 * g = 0.85: f = 0.416, g' = 0.803. Swept in the engine with the shape on
 * (f 0.3 to 0.7, orders 4 to 16) over Mars sun 5, 15 and 30: no other f
 * reads all three day skies better (0.44: sun 30 -0.13, sun 15 -0.04, sun 5
 * +0.08 points), and a larger f brightens the horizon band. */
#define PHASE_DELTA_ORDER 6
void phase_delta_truncation(enum atmo_phase kind, double g, double *ret_f, double *ret_g);

/* The forward peak that the truncation takes out, p_peak = (p - (1 - f)
 * p') / f, as the light it scatters is widened (common.glsl's
 * delta_peak_phase): ret_h, the Henyey-Greenstein parameter with its
 * moment of order PHASE_DELTA_ORDER (n peak scatterings widen a phase of
 * parameter g to g h^n), and ret_spread_rad, its root-mean-square angle
 * from its second moment (small angles: 1 - P_2 ~ 3/2 theta^2), which
 * widens as sqrt(n). Cornette-Shanks g = 0.85: h = 0.924, spread 0.147
 * (8.4 deg). No peak (f = 0): h = 1, spread 0. */
void phase_delta_peak(enum atmo_phase kind, double g, double *ret_h, double *ret_spread_rad);

/* delta_peak_phase's widened phase for the light that the peak scattered
 * besides the last deflection: tau the peak's optical depth toward the
 * light and back to the eye, mu_l the light's cos-zenith at the point, mu
 * the view's cosine with the light. */
double phase_delta_peak_phase(enum atmo_phase kind, double g, double h, double spread_rad, double tau,
			      double mu_l, double mu);

#endif
