/* state.c - the sky state: its defaults, the quality presets, validation
 * and the tables' bookkeeping. Its keys are the registry's (state_keys.c). */
#include "state_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *const state_table_names[STATE_N_TABLES] = {
	"transmittance", "multiscatter", "skyview", "aerial",
};

/* The quality presets behind the key quality=low|medium|high|ultra. medium
 * is the reference of docs/physics.md and the default; it takes at most 20
 * sky-view steps a ray (docs/physics.md: about 4 to 30), where more steps
 * no longer move the error (docs/findings/daemon.md). low halves it,
 * high raises steps by half, ultra doubles sizes and steps (about 8 times
 * the work of medium: more would take seconds on lavapipe). `skybench
 * accuracy` measures their cost and error. Every preset leaves
 * multiscatter_iterations, multiscatter_moment and multiscatter_delta at
 * auto. */
enum quality_preset { QUALITY_LOW, QUALITY_MEDIUM, QUALITY_HIGH, QUALITY_ULTRA, N_QUALITY_PRESETS };

const char *const state_quality_names[N_QUALITY_PRESETS + 1] = {
	[QUALITY_LOW] = "low", [QUALITY_MEDIUM] = "medium", [QUALITY_HIGH] = "high",
	[QUALITY_ULTRA] = "ultra", [N_QUALITY_PRESETS] = NULL,
};

#define TABLE_Q(w, h, d, n) { .width = (w), .height = (h), .depth = (d), .steps = (n) }
static const struct state_quality quality_presets[N_QUALITY_PRESETS] = {
	[QUALITY_LOW] = {
		.t = { [STATE_TRANSMITTANCE] = TABLE_Q(128, 32, 1, 20),
		       [STATE_MULTISCATTER] = TABLE_Q(16, 16, 1, 10),
		       [STATE_SKYVIEW] = TABLE_Q(96, 54, 1, 16),
		       [STATE_AERIAL] = TABLE_Q(16, 16, 16, 1) },
		.multiscatter_dirs = 2, .skyview_min_steps = 4, .aerial_range_km = 128.0,
		.aerial_spacing = STATE_SQUARED, .storage = STATE_F16,
		.cloud_width = 128, .shadow_width = 128, .cloud_cell_texels = 2.0,
	},
	[QUALITY_MEDIUM] = {
		.t = { [STATE_TRANSMITTANCE] = TABLE_Q(256, 64, 1, 40),
		       [STATE_MULTISCATTER] = TABLE_Q(32, 32, 1, 20),
		       [STATE_SKYVIEW] = TABLE_Q(192, 108, 1, 20),
		       [STATE_AERIAL] = TABLE_Q(32, 32, 32, 1) },
		.multiscatter_dirs = 64, .skyview_min_steps = 4, .aerial_range_km = 128.0,
		.aerial_spacing = STATE_SQUARED, .storage = STATE_F32,
		.cloud_width = 256, .shadow_width = 256, .cloud_cell_texels = 2.0,
	},
	[QUALITY_HIGH] = {
		.t = { [STATE_TRANSMITTANCE] = TABLE_Q(256, 64, 1, 60),
		       [STATE_MULTISCATTER] = TABLE_Q(32, 32, 1, 30),
		       [STATE_SKYVIEW] = TABLE_Q(256, 144, 1, 45),
		       [STATE_AERIAL] = TABLE_Q(48, 48, 32, 2) },
		.multiscatter_dirs = 64, .skyview_min_steps = 6, .aerial_range_km = 128.0,
		.aerial_spacing = STATE_SQUARED, .storage = STATE_F32,
		.cloud_width = 256, .shadow_width = 256, .cloud_cell_texels = 2.0,
	},
	[QUALITY_ULTRA] = {
		.t = { [STATE_TRANSMITTANCE] = TABLE_Q(512, 128, 1, 80),
		       [STATE_MULTISCATTER] = TABLE_Q(64, 64, 1, 40),
		       [STATE_SKYVIEW] = TABLE_Q(384, 216, 1, 60),
		       [STATE_AERIAL] = TABLE_Q(64, 64, 64, 2) },
		.multiscatter_dirs = 64, .skyview_min_steps = 8, .aerial_range_km = 128.0,
		.aerial_spacing = STATE_SQUARED, .storage = STATE_F32,
		.cloud_width = 512, .shadow_width = 512, .cloud_cell_texels = 2.0,
	},
};

int state_set_quality(struct sky_state *s, const struct state_key *k, const char *v,
		      uint32_t *ret_dirty, char *err, size_t err_size)
{
	int i;
	int r = state_key_parse(k, v, &i, err, err_size);

	if (r < 0)
		return r;
	s->quality = quality_presets[i];
	/* The cloud tables' sizes change with it; no table while none is drawn. */
	if (!state_clouds_drawn(s))
		*ret_dirty &= ~(uint32_t)STATE_CLOUD_TABLES;
	return 0;
}

int state_get_quality(const struct sky_state *s, const struct state_key *k, char *buf, size_t n)
{
	for (int i = 0; i < N_QUALITY_PRESETS; i++)
		if (memcmp(&quality_presets[i], &s->quality, sizeof(s->quality)) == 0) {
			snprintf(buf, n, "%s", state_quality_names[i]);
			return 0;
		}
	snprintf(buf, n, "custom");
	return 0;
}

void state_default_camera(struct state_camera *ret)
{
	struct sky_state s;

	state_default(&s);
	*ret = s.camera;
}

void state_default(struct sky_state *ret)
{
	struct sky_state s = { 0 };

	/* What no key sets: the clock's anchor on the monotonic clock (0),
	 * the lights' time, the sensor's EV100, the weather's bookkeeping. */
	s.lights_utc_s = NAN;
	s.clouds.utc_s = NAN;
	s.exposure_ev100 = NAN;
	s.weather.cloud_factor = 1.0;
	state_keys_default(&s);
	*ret = s;
}

int state_set_pair(struct sky_state *s, const char *pair, uint32_t *ret_dirty,
		   char *err, size_t err_size)
{
	const char *eq = strchr(pair, '=');
	char key[64];

	if (!eq || eq == pair)
		return ERR("'%s': expected key=value", pair);
	if ((size_t)(eq - pair) >= sizeof(key))
		return ERR("'%.32s...': key too long", pair);
	memcpy(key, pair, eq - pair);
	key[eq - pair] = 0;
	return state_set(s, key, eq + 1, ret_dirty, err, err_size);
}

size_t state_texel_bytes(enum state_storage st)
{
	return st == STATE_F16 ? 8 : 16;
}

size_t state_table_bytes(const struct sky_state *s, enum state_table t)
{
	const struct state_table_quality *q = &s->quality.t[t];
	return (size_t)q->width * q->height * (t == STATE_AERIAL ? q->depth : 1) *
	       state_texel_bytes(s->quality.storage);
}

uint32_t state_multiscatter_iterations(const struct sky_state *s)
{
	if (s->quality.multiscatter_dirs == 0)
		return 0;
	if (s->quality.multiscatter_iterations > 0)
		return (uint32_t)s->quality.multiscatter_iterations - 1;
	/* Not on the 2-direction fast path: its f_ms is too coarse for the
	 * transfer, and iterating spreads its errors instead of correcting
	 * them (docs/findings/daemon.md). */
	if (s->quality.multiscatter_dirs != 64)
		return 0;
	/* The threshold needs a few percent: 1000 intervals are plenty. */
	double tau[3];
	atmo_vertical_optical_depth(&s->atmo, 1000, tau);
	double most = fmax(tau[0], fmax(tau[1], tau[2]));
	return most >= STATE_THICK_OPTICAL_DEPTH ? 2 : 0;
}

int state_validate(const struct sky_state *s, uint64_t max_buffer_bytes,
		   char *err, size_t err_size)
{
	int r = atmo_validate(&s->atmo, err, err_size);
	if (r < 0)
		return r;
	if (!weather_is_empty(&s->weather.in)) {
		/* The weather must fit the atmosphere, and what it makes of it
		 * must be one the engine takes. */
		struct sky_state sky;
		r = state_resolve(s, &sky, NULL, err, err_size);
		if (r < 0 || (r = atmo_validate(&sky.atmo, err, err_size)) < 0)
			return r;
	}
	if ((r = state_clouds_validate(s, err, err_size)) < 0 ||
	    (r = state_terrain_validate(s, err, err_size)) < 0)
		return r;
	if (s->night.zenith_luminance_cd_m2 > 0.0 &&
	    s->night.illuminance_lx < M_PI * s->night.zenith_luminance_cd_m2)
		return ERR_RANGE("night_illuminance_lx: %g is below pi * night_zenith_luminance_cd_m2 = %g (a night sky darker at the horizon than at the zenith)",
			   s->night.illuminance_lx, M_PI * s->night.zenith_luminance_cd_m2);
	if (s->quality.skyview_min_steps > s->quality.t[STATE_SKYVIEW].steps)
		return ERR_RANGE("skyview_min_steps: must not exceed skyview_steps");
	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t bytes = state_table_bytes(s, (enum state_table)t);
		if (max_buffer_bytes && bytes > max_buffer_bytes)
			return ERR_RANGE("%s_width: table of %zu bytes exceeds the device limit of %llu",
				   state_table_names[t], bytes,
				   (unsigned long long)max_buffer_bytes);
	}
	return 0;
}

void state_night_floor(const struct sky_state *s, double *ret_zenith_cd_m2, double *ret_gain)
{
	double lz = s->night.zenith_luminance_cd_m2;

	*ret_zenith_cd_m2 = lz > 0.0 ? lz : 0.0;
	*ret_gain = lz > 0.0 ? fmax(3.0 * (s->night.illuminance_lx / (M_PI * lz) - 1.0), 0.0) : 0.0;
}

/* state_diff's walk: each key of one state whose exact text (every bit of
 * its numbers) the other state does not show, set on a scratch copy of
 * the other to learn its mask. Get's nine digits would hide a difference
 * in the last bits of a value the clock or a METAR computed, and leave
 * tables of a state no longer served. */
struct diff {
	const struct sky_state *other;
	struct sky_state scratch;
	uint32_t dirty;
};

static void diff_key(void *ctx, const char *key, const char *value)
{
	struct diff *d = ctx;
	char other[512], err[256];

	if (state_get_exact(d->other, key, other, sizeof(other)) == 0 && strcmp(other, value) == 0)
		return;
	if (state_set(&d->scratch, key, value, &d->dirty, err, sizeof(err)) < 0)
		d->dirty = STATE_ALL_TABLES;
}

uint32_t state_diff(const struct sky_state *a, const struct sky_state *b)
{
	struct diff *d = malloc(sizeof(*d));
	uint32_t dirty;

	if (!d)
		return STATE_ALL_TABLES;
	/* Both ways: `get` lists some keys only away from their defaults. */
	*d = (struct diff){ .other = a, .scratch = *a };
	state_foreach_exact(b, diff_key, d);
	dirty = d->dirty;
	*d = (struct diff){ .other = b, .scratch = *b };
	state_foreach_exact(a, diff_key, d);
	dirty |= d->dirty;
	free(d);
	/* What no key shows: the raw keys that win over the weather, and a
	 * cloud factor a light sensor set. */
	for (uint32_t bit = 1; bit <= STATE_OVERRIDE_OZONE_ABSORPTION; bit <<= 1)
		if ((a->weather.overridden ^ b->weather.overridden) & bit) {
			const struct state_key *k = state_key_pinning(bit);
			dirty |= k ? k->dirty : STATE_ALL_TABLES;
		}
	if (memcmp(&a->weather.cloud_factor, &b->weather.cloud_factor, sizeof(double)) != 0)
		dirty |= state_key_of(STATE_KEY_ID_CLOUD_OKTAS)->dirty;
	return dirty;
}

/* The cloud tables' names (enum state_cloud_table), as the protocol's. */
static const char *const cloud_table_names[] = { "cloud", "shadow" };

int state_parse_tables(const char *list, uint32_t *ret_mask)
{
	uint32_t mask = 0;
	const char *p = list;

	while (*p) {
		size_t n = strcspn(p, ",");
		int found = 0;
		if (n == 3 && strncmp(p, "all", 3) == 0) {
			mask |= STATE_ALL_TABLES;
			found = 1;
		}
		for (int t = 0; t < STATE_N_TABLES && !found; t++)
			if (strlen(state_table_names[t]) == n &&
			    strncmp(p, state_table_names[t], n) == 0) {
				mask |= STATE_BIT(t);
				found = 1;
			}
		for (int t = STATE_N_TABLES; t < STATE_N_ALL_TABLES && !found; t++)
			if (strlen(cloud_table_names[t - STATE_N_TABLES]) == n &&
			    strncmp(p, cloud_table_names[t - STATE_N_TABLES], n) == 0) {
				mask |= STATE_BIT(t);
				found = 1;
			}
		if (!found)
			return -EINVAL;
		p += n;
		if (*p == ',')
			p++;
	}
	if (!mask)
		return -EINVAL;
	*ret_mask = mask;
	return 0;
}

void state_format_tables(uint32_t mask, char *buf, size_t size)
{
	size_t o = 0;

	buf[0] = 0;
	for (int t = 0; t < STATE_N_TABLES; t++)
		if (mask & STATE_BIT(t))
			o += (size_t)snprintf(buf + o, o < size ? size - o : 0, "%s%s", o ? "," : "",
					      state_table_names[t]);
	if (!o)
		snprintf(buf, size, "none");
}

void state_format_all_tables(uint32_t mask, char *buf, size_t size)
{
	size_t o;

	state_format_tables(mask & STATE_ALL_TABLES, buf, size);
	if (!(mask & STATE_CLOUD_TABLES))
		return;
	o = mask & STATE_ALL_TABLES ? strlen(buf) : 0;
	for (int t = STATE_N_TABLES; t < STATE_N_ALL_TABLES; t++)
		if (mask & STATE_BIT(t))
			o += (size_t)snprintf(buf + o, o < size ? size - o : 0, "%s%s", o ? "," : "",
					      cloud_table_names[t - STATE_N_TABLES]);
}

uint32_t state_closure(uint32_t mask)
{
	if (mask & (S_BIT | A_BIT))
		mask |= M_BIT;
	if (mask & M_BIT)
		mask |= T_BIT;
	return mask;
}
