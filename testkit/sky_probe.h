/* sky_probe.h - a scene's sky-view table from the model or the engine, and
 * its luminance in a direction as a client samples it: what the tests of
 * the multi-scattering terms (test_moment, test_delta) compare; and a
 * state from key=value pairs and its sky-view and aerial perspective (the
 * shadow tests). */
#ifndef SKYD_SKY_PROBE_H
#define SKYD_SKY_PROBE_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "eng.h"
#include "model.h"
#include "skysample.h"
#include "test.h"

static inline void probe_set(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0)
		FAIL("%s", err);
}

/* The resolved state of the default's with the space-separated pairs set
 * on top, or -1 (failed, said). */
static inline int probe_state_of(const char *pairs, struct sky_state *ret)
{
	struct sky_state s;
	char err[256], copy[768];

	state_default(&s);
	snprintf(copy, sizeof(copy), "%s", pairs);
	for (char *save, *p = strtok_r(copy, " ", &save); p; p = strtok_r(NULL, " ", &save))
		if (state_set_pair(&s, p, NULL, err, sizeof(err)) < 0) {
			FAIL("%s: %s", pairs, err);
			return -1;
		}
	if (state_resolve(&s, ret, NULL, err, sizeof(err)) < 0) {
		FAIL("%s: %s", pairs, err);
		return -1;
	}
	return 0;
}

/* Mars at 0.2 km with the sun 5 deg up at azimuth 180: where the
 * isotropic phase is furthest from the truth (docs/accuracy.md), with
 * `pair` (the other term's knob) set on top. */
static inline void probe_mars_sun5(struct sky_state *s, const char *pair)
{
	state_default(s);
	probe_set(s, "preset=mars");
	probe_set(s, "sun_elevation_deg=5");
	probe_set(s, "sun_azimuth_deg=180");
	probe_set(s, "altitude_km=0.2");
	probe_set(s, pair);
}

/* The rule of a term that `knob`=auto|off|on switches and pick (phase.h)
 * names the constituent of: none for the default Earth, the Mie layer when
 * forced on, Mars' dust under auto, none when off or with 2 directions. */
static inline void probe_check_rule(int (*pick)(const struct sky_state *, const double *),
				    const char *knob)
{
	struct sky_state s;
	char on[64], off[64];
	snprintf(on, sizeof(on), "%s=on", knob);
	snprintf(off, sizeof(off), "%s=off", knob);
	state_default(&s);
	CHECK(pick(&s, NULL) == -1);
	probe_set(&s, on);
	int mie = pick(&s, NULL);
	CHECK(mie >= 0 && s.atmo.c[mie].phase != ATMO_PHASE_RAYLEIGH && s.atmo.c[mie].g > 0.5);
	state_default(&s);
	probe_set(&s, "preset=mars");
	int dust = pick(&s, NULL);
	CHECK(dust >= 0 && s.atmo.c[dust].g > 0.8);
	probe_set(&s, off);
	CHECK(pick(&s, NULL) == -1);
	probe_set(&s, on);
	probe_set(&s, "multiscatter_dirs=2");
	CHECK(pick(&s, NULL) == -1);
}

/* Luminance of a float32 sky-view table of s in a direction. */
static inline double probe_sky_lum(const float *texels, const struct sky_state *s, double el_deg,
				   double az_deg)
{
	struct skysample_table t = { .texels = texels, .format = SKY_FORMAT_RGBA32F,
				     .width = s->quality.t[STATE_SKYVIEW].width,
				     .height = s->quality.t[STATE_SKYVIEW].height, .depth = 1 };
	struct sky_shm_state st = { .altitude_km = s->altitude_km,
				    .bottom_radius_km = s->atmo.bottom_radius_km,
				    .top_radius_km = s->atmo.top_radius_km };
	double rgb[3];
	skysample_sky(&t, &st, el_deg * M_PI / 180.0, az_deg * M_PI / 180.0, rgb);
	return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* The model's sky-view table of s as float32 texels (free()); arg unused,
 * so that it and probe_engine_sky fit one callback type. */
static inline float *probe_model_sky(void *arg, const struct sky_state *s)
{
	(void)arg;
	struct model_tables m;
	CHECK(model_compute(s, STATE_BIT(STATE_SKYVIEW), &m) == 0);
	size_t n = 4 * (size_t)m.w[STATE_SKYVIEW] * m.h[STATE_SKYVIEW];
	float *f = malloc(sizeof(float) * n);
	if (!f)
		abort();
	for (size_t i = 0; i < n; i++)
		f[i] = (float)m.t[STATE_SKYVIEW][i];
	model_tables_finish(&m);
	return f;
}

/* The engine's (arg: struct eng *) sky-view table of s as float32 texels
 * (free()), or NULL. The engine computes exactly the mask it is given, and
 * the terms under test are the multi-scattering pass's: the closure. */
static inline float *probe_engine_sky(void *arg, const struct sky_state *s)
{
	char err[512];
	struct eng_timing t;
	size_t bytes;
	if (eng_compute(arg, s, state_closure(STATE_BIT(STATE_SKYVIEW)), &t, err, sizeof(err)) < 0) {
		FAIL("eng_compute: %s", err);
		return NULL;
	}
	const void *texels = eng_table(arg, STATE_SKYVIEW, &bytes);
	float *f = malloc(bytes);
	if (!f)
		abort();
	memcpy(f, texels, bytes);
	return f;
}

/* Every table of s from the engine e, then its sky-view and aerial
 * perspective as float32 texels (ret[0], ret[1]: free()) and their float
 * counts; the computation's wall time in *ret_ms if not NULL. 0, or -1
 * (a FAIL said why where the engine refused). */
static inline int probe_sky_aerial(struct eng *e, const struct sky_state *s, float *ret[2], size_t ret_n[2],
				   double *ret_ms)
{
	struct eng_timing t;
	char err[512];
	if (eng_compute(e, s, STATE_ALL_TABLES, &t, err, sizeof(err)) < 0) {
		FAIL("eng_compute: %s", err);
		return -1;
	}
	if (ret_ms)
		*ret_ms = t.total_ms;
	for (int k = 0; k < 2; k++) {
		size_t bytes;
		const void *p = eng_table(e, k == 0 ? STATE_SKYVIEW : STATE_AERIAL, &bytes);
		ret[k] = p ? malloc(bytes) : NULL;
		if (!ret[k])
			return -1;
		memcpy(ret[k], p, bytes);
		ret_n[k] = bytes / sizeof(float);
	}
	return 0;
}

typedef float *probe_sky_fn(void *arg, const struct sky_state *s);

struct probe_dir {
	double el_deg, az_deg;
};

/* Sky luminance of s0 with on_pair over off_pair set on it, in n
 * directions, from sky (probe_model_sky or probe_engine_sky). */
static inline void probe_on_off(probe_sky_fn *sky, void *arg, const struct sky_state *s0,
				const char *on_pair, const char *off_pair, const struct probe_dir *dirs,
				size_t n, double *ret)
{
	struct sky_state s = *s0;
	probe_set(&s, on_pair);
	float *on = sky(arg, &s);
	probe_set(&s, off_pair);
	float *off = sky(arg, &s);
	for (size_t i = 0; on && off && i < n; i++)
		ret[i] = probe_sky_lum(on, &s, dirs[i].el_deg, dirs[i].az_deg) /
			 probe_sky_lum(off, &s, dirs[i].el_deg, dirs[i].az_deg);
	free(on);
	free(off);
}

#endif
