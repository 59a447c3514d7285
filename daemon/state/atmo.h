/* atmo.h - the atmosphere as data: planet, shell, constituents, profiles.
 *
 * Earth, Mars and made-up planets are values of struct atmo, never code.
 * Lengths in km, coefficients in 1/km, per RGB channel (680, 550, 440 nm).
 */
#ifndef SKYD_ATMO_H
#define SKYD_ATMO_H

#include <stddef.h>

#define ATMO_MAX_CONSTITUENTS 4
#define ATMO_NAME_MAX 16

enum atmo_phase {
	ATMO_PHASE_NONE = 0,		/* absorbs only; scattering must be 0 */
	ATMO_PHASE_RAYLEIGH = 1,
	ATMO_PHASE_CORNETTE_SHANKS = 2,
	ATMO_PHASE_HENYEY_GREENSTEIN = 3,
};

/* One layer of a density profile, Bruneton's DensityProfileLayer:
 *   density(h) = clamp(exp_term * exp(exp_scale_per_km * h)
 *                      + linear_per_km * h + constant, 0, 1)
 * with h the altitude in km. */
struct atmo_layer {
	double width_km;
	double exp_term;
	double exp_scale_per_km;
	double linear_per_km;
	double constant;
};

/* Two layers: layers[0] below layers[0].width_km, layers[1] above. */
struct atmo_profile {
	struct atmo_layer layers[2];
};

struct atmo_constituent {
	char name[ATMO_NAME_MAX];
	double scattering_per_km[3];
	double absorption_per_km[3];
	enum atmo_phase phase;
	double g;			/* asymmetry, for CS and HG; |g| < 1 */
	struct atmo_profile density;
};

struct atmo {
	double bottom_radius_km;
	double top_radius_km;
	double ground_albedo[3];
	int n_constituents;
	struct atmo_constituent c[ATMO_MAX_CONSTITUENTS];
};

/* Index of the well-known constituents in the presets. */
enum { ATMO_RAYLEIGH = 0, ATMO_MIE = 1, ATMO_OZONE = 2 };

/* Hillaire's EGSR 2020 Earth with the constants of docs/physics.md. */
void atmo_earth(struct atmo *ret);
/* Mars after Collienne 2013 (OpenSpace). */
void atmo_mars(struct atmo *ret);
/* The presets' names, NULL-terminated: earth, mars. */
extern const char *const atmo_preset_names[];
/* Fills ret from a preset name (atmo_preset_names); -EINVAL if unknown. */
int atmo_preset(const char *name, struct atmo *ret);

/* Density of a profile at altitude_km, in [0, 1]. */
double atmo_density(const struct atmo_profile *p, double altitude_km);

/* Checks every rule the engine relies on. Returns 0, or -EINVAL with a
 * message naming the key and the rule in err (never NULL-terminated short). */
int atmo_validate(const struct atmo *a, char *err, size_t err_size);

/* Vertical optical depth per channel from the ground to the top, summed over
 * constituents, by composite Simpson with n intervals. */
void atmo_vertical_optical_depth(const struct atmo *a, int n, double ret_tau[3]);

#endif
