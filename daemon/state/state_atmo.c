/* state_atmo.c - the atmosphere's keys in the sky's state: the planet
 * preset and the hooks of the constituent family ("<constituent>_<field>",
 * rows in state_keys.c), which read and write struct atmo (atmo.h). */
#include "state_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

const char *const state_phase_names[] = {
	[ATMO_PHASE_NONE] = "none", [ATMO_PHASE_RAYLEIGH] = "rayleigh",
	[ATMO_PHASE_CORNETTE_SHANKS] = "cornette_shanks",
	[ATMO_PHASE_HENYEY_GREENSTEIN] = "henyey_greenstein", NULL,
};

int state_set_preset(struct sky_state *s, const struct state_key *k, const char *v,
		     uint32_t *ret_dirty, char *err, size_t err_size)
{
	int i;
	int r = state_key_parse(k, v, &i, err, err_size);

	if (r < 0 || (r = atmo_preset(v, &s->atmo)) < 0)
		return r;
	snprintf(s->preset, sizeof(s->preset), "%s", v);
	/* The raw keys the overrides kept are gone with the old atmosphere. */
	s->weather.overridden = 0;
	return 0;
}

int state_get_preset(const struct sky_state *s, const struct state_key *k, char *buf, size_t n)
{
	snprintf(buf, n, "%s", s->preset);
	return 0;
}

/* The constituent a key of the family belongs to: the one whose name the
 * key's starts with, NULL when the state's preset has none. */
static const struct atmo_constituent *constituent_of(const struct sky_state *s,
						     const struct state_key *k)
{
	for (int i = 0; i < s->atmo.n_constituents; i++) {
		size_t n = strlen(s->atmo.c[i].name);
		if (n && strncmp(k->name, s->atmo.c[i].name, n) == 0 && k->name[n] == '_')
			return &s->atmo.c[i];
	}
	return NULL;
}

/* The number a field names: a layer's, or the constituent's g. */
static double *number_field(struct atmo_constituent *c, int arg)
{
	struct atmo_layer *l = &c->density.layers[arg >= STATE_C_UPPER];

	switch (arg % STATE_C_UPPER) {
	case STATE_C_WIDTH: return &l->width_km;
	case STATE_C_EXP_TERM: return &l->exp_term;
	case STATE_C_EXP_SCALE: return &l->exp_scale_per_km;
	case STATE_C_LINEAR: return &l->linear_per_km;
	case STATE_C_CONSTANT: return &l->constant;
	default: return &c->g;
	}
}

static int parse_constituent(struct atmo_constituent *c, const struct state_key *k, const char *v,
			     char *err, size_t err_size)
{
	double d, t[3];
	int i;

	switch (k->arg) {
	case STATE_C_PHASE:
		if (state_key_parse(k, v, &i, err, err_size) < 0)
			return -EINVAL;
		c->phase = (enum atmo_phase)i;
		return 0;
	case STATE_C_SCATTERING:
	case STATE_C_ABSORPTION:
		if (state_key_parse(k, v, t, err, err_size) < 0)
			return -EINVAL;
		for (i = 0; i < 3; i++)
			if (t[i] < 0.0)
				return ERR_RANGE("%s: coefficients must be >= 0", k->name);
		memcpy(k->arg == STATE_C_SCATTERING ? c->scattering_per_km : c->absorption_per_km, t,
		       sizeof(t));
		return 0;
	}
	if (state_key_parse(k, v, &d, err, err_size) < 0)
		return -EINVAL;
	if (k->arg == STATE_C_SCALE_HEIGHT) {
		if (!(d > 0.0))
			return ERR_RANGE("%s: must be > 0", k->name);
		c->density = (struct atmo_profile){ 0 };
		c->density.layers[1].exp_term = 1.0;
		c->density.layers[1].exp_scale_per_km = -1.0 / d;
		return 0;
	}
	if (k->arg == STATE_C_G && !(fabs(d) < 1.0))
		return ERR_RANGE("%s: must satisfy |g| < 1", k->name);
	if (k->arg == STATE_C_WIDTH && d < 0.0)
		return ERR_RANGE("%s: must be >= 0", k->name);
	*number_field(c, k->arg) = d;
	return 0;
}

int state_set_constituent(struct sky_state *s, const struct state_key *k, const char *v,
			  uint32_t *ret_dirty, char *err, size_t err_size)
{
	struct atmo_constituent *c = (struct atmo_constituent *)constituent_of(s, k);

	if (!c)
		return ERR_UNKNOWN("%s: unknown key", k->name);
	int r = parse_constituent(c, k, v, err, err_size);
	if (r == 0)
		state_weather_pin(s, k->override);
	return r;
}

int state_get_constituent(const struct sky_state *s, const struct state_key *k, char *buf,
			  size_t n)
{
	const struct atmo_constituent *c = constituent_of(s, k);
	const struct atmo_layer *upper = c ? &c->density.layers[1] : NULL;

	if (!c)
		return -ENOENT;
	switch (k->arg) {
	case STATE_C_SCATTERING:
		state_key_format(k, c->scattering_per_km, buf, n);
		break;
	case STATE_C_ABSORPTION:
		state_key_format(k, c->absorption_per_km, buf, n);
		break;
	case STATE_C_SCALE_HEIGHT:
		/* Defined only for a pure exponential profile. */
		if (upper->exp_scale_per_km < 0 && c->density.layers[0].width_km == 0)
			state_format_number(-1.0 / upper->exp_scale_per_km, buf, n);
		else
			snprintf(buf, n, "none");
		break;
	case STATE_C_PHASE: {
		int phase = (int)c->phase;
		state_key_format(k, &phase, buf, n);
		break;
	}
	default:
		state_key_format(k, number_field((struct atmo_constituent *)c, k->arg), buf, n);
		break;
	}
	return 0;
}
