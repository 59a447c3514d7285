/* sos.h - a second, independent truth for the path tracer: the sky radiance
 * of a plane-parallel, conservative Rayleigh layer over a black ground by
 * successive orders of scattering, scalar or with polarization.
 *
 * Rayleigh scattering depends on the light arriving at a point only through
 * one 3 x 3 matrix, the integral over directions of the light's coherency
 * (polarization) tensor: the scattered tensor toward n is k P_n M P_n, with
 * P_n = 1 - n n^T and k = 3 / (8 pi). The solver iterates M(tau) on a grid
 * of optical depth (each order one sweep up and one down along 2 x streams
 * cosines by 8 azimuths, exact for the quartic azimuthal terms); the first
 * order is integrated in closed form. The scalar problem is the same with
 * every scattered tensor made unpolarized (trace / 2 times P_n), which is
 * the phase 3 / (16 pi) (1 + cos^2) of the path tracer and the sky tables.
 *
 * In a conservative layer of a single phase the radiance at its boundaries
 * depends on the total optical depth only, not on how the scatterers are
 * spread with height: the same answer holds for Earth's air alone (Rayleigh,
 * no Mie, no ozone) in the plane-parallel limit.
 */
#ifndef SKYD_SOS_H
#define SKYD_SOS_H

#include <stddef.h>
#include <stdint.h>

struct sos_layer {
	double tau;			/* vertical optical depth, > 0 */
	double sun_elevation_deg;	/* (0, 90] */
	double irradiance;		/* of the beam, on a surface normal to it */
	int polarized;			/* 1: Stokes I of the vector problem; 0: scalar */
	uint32_t layers;		/* grid in tau (0: 400) */
	uint32_t streams;		/* Gauss cosines per hemisphere (0: 48) */
};

/* A view: elevation_deg < 0 looks down from above the layer (reflected
 * light), > 0 looks up from below it (transmitted, diffuse only);
 * azimuth_deg from the sun's azimuth (0: toward the sun's side). */
struct sos_view {
	double elevation_deg;
	double azimuth_deg;
};

/* The radiance (the unit of irradiance per sr) seen in n views, into
 * ret_radiance[n]; ret_orders (may be NULL) the number of orders summed
 * until an order added less than 1e-13 of the total. Returns 0, -EINVAL
 * for bad arguments (a view within 1e-6 of horizontal), or -ENOMEM. */
int sos_rayleigh(const struct sos_layer *l, const struct sos_view *views, size_t n,
		 double *ret_radiance, int *ret_orders);

#endif
