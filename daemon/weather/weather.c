/* weather.c - weather inputs and their mapping onto the Mie and ozone
 * constituents and the cloud light factor (docs/weather.md). Their keys
 * are the state's (daemon/state/state_keys.c). */
#include "weather.h"

#include "proto.h"

#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Koschmieder's constant -ln(0.02): the range at which a black object's
 * contrast against the horizon sky falls to the 2 % threshold. */
#define KOSCHMIEDER 3.912
/* OPAC tabulates its mixtures at 80 % relative humidity: the reference of
 * the growth law. Above 99 % the law diverges; fog is taken at 99 %. */
#define RH_REF 0.80
#define RH_MAX 0.99
/* Molecules per m^2 in one Dobson unit (a 10 um layer at 0 C, 1013.25 hPa). */
#define DOBSON_PER_M2 2.687e20
/* Scale heights fitted from (turbidity, visibility) pairs stay within this. */
#define FIT_SCALE_HEIGHT_MIN_KM 0.1
#define FIT_SCALE_HEIGHT_MAX_KM 10.0

static const double channel_nm[3] = { 680.0, 550.0, 440.0 };

/* Ozone absorption cross-sections at 293 K (m^2 per molecule) at the three
 * channels, from the Bremen measurements (Serdyuchenko et al. 2014,
 * Gorshelev et al. 2014) as tabulated every 10 nm in Bruneton's 2017
 * precomputed atmospheric scattering. */
static const double ozone_cross_section_m2[3] = { 1.209e-25, 3.5e-25, 1.582e-26 };

/* One aerosol type: OPAC's mixture at 80 % RH and 550 nm (Hess, Koepke and
 * Schult 1998, table 4: single-scattering albedo, asymmetry, Angstrom
 * exponents over 350-500 and 500-800 nm, optical depth), its height profile
 * (exponential of scale Z within a mixing layer of height H_M, OPAC's
 * default profiles) and the exponent of its humidity growth. */
struct aerosol_type {
	double ssa, g, alpha_short, alpha_long, aod_550;
	double profile_scale_km, mixing_height_km;
	double gamma;
};

const char *const weather_aerosol_names[WEATHER_N_AEROSOLS + 1] = {
	[WEATHER_AEROSOL_AUTO] = "auto", [WEATHER_CLEAN] = "clean",
	[WEATHER_CONTINENTAL] = "continental", [WEATHER_URBAN] = "urban",
	[WEATHER_MARITIME] = "maritime", [WEATHER_DESERT] = "desert", [WEATHER_N_AEROSOLS] = NULL,
};

static const struct aerosol_type aerosol_types[WEATHER_N_AEROSOLS] = {
	[WEATHER_CLEAN] = { 0.972, 0.709, 1.10, 1.42, 0.064, 8.0, 2.0, 0.30 },
	[WEATHER_CONTINENTAL] = { 0.925, 0.703, 1.11, 1.42, 0.151, 8.0, 2.0, 0.30 },
	[WEATHER_URBAN] = { 0.817, 0.689, 1.14, 1.43, 0.643, 8.0, 2.0, 0.25 },
	[WEATHER_MARITIME] = { 0.997, 0.772, 0.12, 0.08, 0.096, 1.0, 2.0, 0.60 },
	[WEATHER_DESERT] = { 0.888, 0.729, 0.20, 0.17, 0.286, 2.0, 6.0, 0.10 },
};

void weather_init(struct weather *ret)
{
	*ret = (struct weather){
		.visibility_km = NAN, .relative_humidity = NAN, .aerosol = WEATHER_AEROSOL_AUTO,
		.angstrom_beta = NAN, .ozone_du = NAN, .cloud_oktas = NAN,
	};
}

bool weather_is_empty(const struct weather *w)
{
	return isnan(w->visibility_km) && isnan(w->relative_humidity) &&
	       w->aerosol == WEATHER_AEROSOL_AUTO && isnan(w->angstrom_beta) &&
	       isnan(w->ozone_du) && isnan(w->cloud_oktas);
}

static bool same(double a, double b)
{
	return (isnan(a) && isnan(b)) || a == b;
}

bool weather_equal(const struct weather *a, const struct weather *b)
{
	return same(a->visibility_km, b->visibility_km) &&
	       same(a->relative_humidity, b->relative_humidity) && a->aerosol == b->aerosol &&
	       same(a->angstrom_beta, b->angstrom_beta) && same(a->ozone_du, b->ozone_du) &&
	       same(a->cloud_oktas, b->cloud_oktas);
}

const char *weather_aerosol_name(enum weather_aerosol t)
{
	return t >= 0 && t < WEATHER_N_AEROSOLS ? weather_aerosol_names[t] : "invalid";
}

/* An input out of its range: the message names its field of struct
 * weather, the key that sets it. */
#define OUTSIDE(w, field, lo, hi) (!isnan((w)->field) && !((w)->field >= (lo) && (w)->field <= (hi)))
#define REFUSE_OUTSIDE(w, field, lo, hi)                                                    \
	do {                                                                                \
		if (OUTSIDE(w, field, lo, hi)) {                                            \
			snprintf(err, err_size, #field ": %g is outside [%g, %g]", (w)->field, \
				 (double)(lo), (double)(hi));                                \
			return -ERANGE;                                                     \
		}                                                                           \
	} while (0)

int weather_validate(const struct weather *w, char *err, size_t err_size)
{
	REFUSE_OUTSIDE(w, visibility_km, WEATHER_VISIBILITY_MIN_KM, WEATHER_VISIBILITY_MAX_KM);
	REFUSE_OUTSIDE(w, relative_humidity, 0.0, 1.0);
	if (w->aerosol < 0 || w->aerosol >= WEATHER_N_AEROSOLS) {
		snprintf(err, err_size, "aerosol: unknown type %d", (int)w->aerosol);
		return -ERANGE;
	}
	REFUSE_OUTSIDE(w, angstrom_beta, 0.0, WEATHER_ANGSTROM_BETA_MAX);
	REFUSE_OUTSIDE(w, ozone_du, 0.0, WEATHER_OZONE_DU_MAX);
	REFUSE_OUTSIDE(w, cloud_oktas, 0.0, WEATHER_OKTAS_MAX);
	return 0;
}

/* ---- physics ---- */

double weather_cloud_light_factor(double oktas)
{
	if (isnan(oktas))
		return 1.0;
	double n = fmin(fmax(oktas, 0.0), 8.0) / 8.0;
	return 1.0 - 0.75 * pow(n, 3.4);
}

/* Saturation vapour pressure over water, hPa (Alduchov and Eskridge 1996). */
static double magnus_hpa(double t_c)
{
	return 6.1094 * exp(17.625 * t_c / (t_c + 243.04));
}

double weather_relative_humidity(double temperature_c, double dewpoint_c)
{
	if (!isfinite(temperature_c) || !isfinite(dewpoint_c))
		return NAN;
	return magnus_hpa(dewpoint_c) / magnus_hpa(temperature_c);
}

static int find_constituent(const struct atmo *a, const char *name)
{
	for (int i = 0; i < a->n_constituents; i++)
		if (strcmp(a->c[i].name, name) == 0)
			return i;
	return -1;
}

/* Extinction at 550 nm at the ground of every constituent but skip (-1:
 * none skipped). */
static double ground_extinction_550(const struct atmo *a, int skip)
{
	double e = 0.0;
	for (int i = 0; i < a->n_constituents; i++) {
		if (i == skip)
			continue;
		const struct atmo_constituent *c = &a->c[i];
		e += (c->scattering_per_km[1] + c->absorption_per_km[1]) *
		     atmo_density(&c->density, 0.0);
	}
	return e;
}

double weather_visibility_km(const struct atmo *a)
{
	double e = ground_extinction_550(a, -1);
	return e > 0.0 ? KOSCHMIEDER / e : INFINITY;
}

/* Most steps of profile_column_km: 0.05 km steps up to a shell of
 * 10,000 km. It runs on the loop for every change, and a shell as thick as
 * the keys allow (1e7 km) took seconds at 0.05 km; a thicker shell gets
 * longer steps instead. */
#define PROFILE_STEPS_MAX 200000

/* Integral of a density profile over the shell, km, by composite Simpson
 * on 0.05 km steps (exact for the piecewise linear ozone tent). */
static double profile_column_km(const struct atmo *a, const struct atmo_profile *p)
{
	double shell = a->top_radius_km - a->bottom_radius_km;
	int n = (int)ceil(fmin(shell / 0.05, PROFILE_STEPS_MAX));
	if (n < 2)
		n = 2;
	if (n % 2)
		n++;
	double dh = shell / n, sum = 0.0;
	for (int j = 0; j <= n; j++) {
		double w = (j == 0 || j == n) ? 1.0 : (j % 2 ? 4.0 : 2.0);
		sum += w * atmo_density(p, j * dh);
	}
	return sum * dh / 3.0;
}

double weather_ozone_du(const struct atmo *a)
{
	int i = find_constituent(a, "ozone");
	if (i < 0)
		return 0.0;
	const struct atmo_constituent *o = &a->c[i];
	/* Number density at density 1, per m^3, times the column in m. */
	double n_per_m3 = o->absorption_per_km[1] * 1e-3 / ozone_cross_section_m2[1];
	return n_per_m3 * profile_column_km(a, &o->density) * 1e3 / DOBSON_PER_M2;
}

/* Optical properties of type t at relative humidity rh (<= RH_MAX): the
 * Hanel growth law scales scattering by f; the absorbing cores do not grow,
 * so absorption stays and the single-scattering albedo rises; the radius
 * grows as sqrt(f), shrinking the Angstrom exponents by that factor and
 * (1 - g) by its power -0.3 (closures of this model, docs/weather.md). */
static void aerosol_optics(const struct aerosol_type *t, double rh, struct weather_map *m)
{
	double f = pow((1.0 - rh) / (1.0 - RH_REF), -t->gamma);
	double radius = sqrt(f);

	m->growth = f;
	m->ssa = f * t->ssa / (f * t->ssa + (1.0 - t->ssa));
	m->angstrom_440_550 = t->alpha_short / radius;
	m->angstrom_550_680 = t->alpha_long / radius;
	m->mie.g = 1.0 - (1.0 - t->g) * pow(radius, -0.3);
	/* One exponential with OPAC's mixing-layer column per unit ground
	 * extinction: Z (1 - exp(-H_M / Z)). */
	m->mie.scale_height_km = t->profile_scale_km *
				 -expm1(-t->mixing_height_km / t->profile_scale_km);
}

/* The Mie part of the map: loading from visibility, turbidity or the
 * type's climatology, spread over the channels by the Angstrom law. */
static void map_mie(const struct weather *w, double air_550, struct weather_map *m)
{
	m->aerosol = w->aerosol == WEATHER_AEROSOL_AUTO ? WEATHER_CONTINENTAL : w->aerosol;
	const struct aerosol_type *t = &aerosol_types[m->aerosol];
	m->relative_humidity = isnan(w->relative_humidity) ? RH_REF
							   : fmin(w->relative_humidity, RH_MAX);
	aerosol_optics(t, m->relative_humidity, m);

	double ext, h = m->mie.scale_height_km;
	/* Turbidity: the 500-800 nm exponent carried on to 1000 nm. */
	double aod_beta = w->angstrom_beta * pow(550.0 / 1000.0, -m->angstrom_550_680);
	if (!isnan(w->visibility_km)) {
		ext = fmax(KOSCHMIEDER / w->visibility_km - air_550, 0.0);
		if (!isnan(w->angstrom_beta) && ext > 0.0)
			h = fmin(fmax(aod_beta / ext, FIT_SCALE_HEIGHT_MIN_KM),
				 FIT_SCALE_HEIGHT_MAX_KM);
	} else if (!isnan(w->angstrom_beta)) {
		ext = aod_beta / h;
	} else {
		ext = t->aod_550 * m->growth / h;
	}
	m->mie.scale_height_km = h;
	m->extinction_550_per_km = ext;
	m->aod_550 = ext * h;

	double e[3] = {
		ext * pow(channel_nm[0] / 550.0, -m->angstrom_550_680),
		ext,
		ext * pow(channel_nm[2] / 550.0, -m->angstrom_440_550),
	};
	for (int ch = 0; ch < 3; ch++) {
		m->mie.scattering_per_km[ch] = e[ch] * m->ssa;
		m->mie.absorption_per_km[ch] = e[ch] * (1.0 - m->ssa);
	}
	m->visibility_km = air_550 + ext > 0.0 ? KOSCHMIEDER / (air_550 + ext) : INFINITY;
}

/* The ozone part: scale to the asked column, or from the cross-sections
 * when the atmosphere's ozone absorbs nothing. */
static int map_ozone(const struct weather *w, const struct atmo *a, struct weather_map *m,
		     char *err, size_t err_size)
{
	int i = find_constituent(a, "ozone");
	double du = weather_ozone_du(a);

	m->ozone_du = du;
	m->ozone_scale = 1.0;
	if (isnan(w->ozone_du))
		return 0;
	if (i < 0) {
		snprintf(err, err_size, "ozone_du: the atmosphere has no ozone constituent");
		return -EINVAL;
	}
	const struct atmo_constituent *o = &a->c[i];
	m->sets_ozone = true;
	m->ozone_du = w->ozone_du;
	if (du > 0.0) {
		m->ozone_scale = w->ozone_du / du;
		for (int ch = 0; ch < 3; ch++)
			m->ozone_absorption_per_km[ch] = o->absorption_per_km[ch] * m->ozone_scale;
		return 0;
	}
	double column_km = profile_column_km(a, &o->density);
	if (column_km <= 0.0) {
		if (w->ozone_du == 0.0)
			return 0;	/* already none */
		snprintf(err, err_size, "ozone_du: the ozone constituent's profile is empty");
		return -EINVAL;
	}
	m->ozone_scale = NAN;
	double n_per_m3 = w->ozone_du * DOBSON_PER_M2 / (column_km * 1e3);
	for (int ch = 0; ch < 3; ch++)
		m->ozone_absorption_per_km[ch] = n_per_m3 * ozone_cross_section_m2[ch] * 1e3;
	return 0;
}

int weather_map(const struct weather *w, const struct atmo *a, struct weather_map *ret,
		char *err, size_t err_size)
{
	struct weather_map m = { 0 };
	int rc = weather_validate(w, err, err_size);
	if (rc < 0)
		return rc;

	int mie = find_constituent(a, "mie");
	m.sets_mie = !isnan(w->visibility_km) || !isnan(w->relative_humidity) ||
		     w->aerosol != WEATHER_AEROSOL_AUTO || !isnan(w->angstrom_beta);
	if (m.sets_mie && mie < 0) {
		/* Named after the first aerosol input given. */
#define FIELD(f) #f
		snprintf(err, err_size, "%s: the atmosphere has no mie constituent",
			 !isnan(w->visibility_km) ? FIELD(visibility_km)
			 : !isnan(w->relative_humidity) ? FIELD(relative_humidity)
			 : !isnan(w->angstrom_beta) ? FIELD(angstrom_beta) : FIELD(aerosol));
#undef FIELD
		return -EINVAL;
	}
	double air_550 = ground_extinction_550(a, mie);
	if (m.sets_mie) {
		map_mie(w, air_550, &m);
	} else {
		m.aerosol = w->aerosol;
		m.relative_humidity = w->relative_humidity;
		m.visibility_km = weather_visibility_km(a);
	}
	rc = map_ozone(w, a, &m, err, err_size);
	if (rc < 0)
		return rc;
	m.light_factor = weather_cloud_light_factor(w->cloud_oktas);
	*ret = m;
	return 0;
}

void weather_apply(const struct weather_map *m, struct atmo *a)
{
	int mie = find_constituent(a, "mie"), ozone = find_constituent(a, "ozone");

	if (m->sets_mie && mie >= 0) {
		struct atmo_constituent *c = &a->c[mie];
		for (int ch = 0; ch < 3; ch++) {
			c->scattering_per_km[ch] = m->mie.scattering_per_km[ch];
			c->absorption_per_km[ch] = m->mie.absorption_per_km[ch];
		}
		c->g = m->mie.g;
		c->density = (struct atmo_profile){ 0 };
		c->density.layers[1].exp_term = 1.0;
		c->density.layers[1].exp_scale_per_km = -1.0 / m->mie.scale_height_km;
	}
	if (m->sets_ozone && ozone >= 0)
		for (int ch = 0; ch < 3; ch++)
			a->c[ozone].absorption_per_km[ch] = m->ozone_absorption_per_km[ch];
}
