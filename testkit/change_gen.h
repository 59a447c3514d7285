/* change_gen.h - seeded random changes of the sky for the convergence
 * tests: request lines of set, batch ... end and set metar=, each valid, so
 * that every one is accepted; the same seed gives the same lines. Needs
 * test.h (test_uniform). */
#ifndef SKYD_CHANGE_GEN_H
#define SKYD_CHANGE_GEN_H

#include <inttypes.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"

/* A key the generator sets, over a range it keeps valid whatever else is
 * set; words (NULL-terminated) instead of the range where it takes them.
 * clock: whether the key touches the clock (time, place or a light mode):
 * a generator without the clock leaves them out. */
struct change_key {
	const char *name;
	double lo, hi;
	const char *const *words;
	int clock;
};

static const char *const change_gen_auto[] = { "auto", NULL };
static const char *const change_gen_modes[] = { "clock", NULL };

static const struct change_key change_keys[] = {
	{ "sun_elevation_deg", -8, 85, NULL, 0 },
	{ "sun_azimuth_deg", 0, 360, NULL, 0 },
	{ "sun_angular_radius_deg", 0.2, 0.35, NULL, 0 },
	{ "moon_elevation_deg", -10, 70, NULL, 0 },
	{ "moon_illuminance_lx", 0, 0.3, NULL, 0 },
	{ "ground_albedo", 0, 0.9, NULL, 0 },
	{ "altitude_km", 0, 3, NULL, 0 },
	{ "camera_yaw_deg", 0, 360, NULL, 0 },
	{ "camera_pitch_deg", -30, 30, NULL, 0 },
	{ "mie_g", 0.6, 0.9, NULL, 0 },
	{ "night_illuminance_lx", 0.001, 0.01, NULL, 0 },
	{ "visibility_km", 5, 80, change_gen_auto, 0 },
	{ "relative_humidity", 0, 0.95, change_gen_auto, 0 },
	{ "cloud_oktas", 0, 8, change_gen_auto, 0 },
	{ "lat_deg", -60, 60, NULL, 1 },
	{ "lon_deg", -180, 180, NULL, 1 },
	{ "sun_mode", 0, 0, change_gen_modes, 1 },
	{ "moon_mode", 0, 0, change_gen_modes, 1 },
};

/* Reports made up in the style of real ones (tests/data/metar). */
static const char *const change_metars[] = {
	"KJFK 121751Z 31012G20KT 10SM FEW050 SCT250 22/08 A3002",
	"KLAX 121853Z VRB04KT 3SM HZ FU BKN008 OVC015 18/14 A2994",
	"KSFO 180556Z 28006KT 1/4SM FG VV001 12/12 A3001",
	"EGLL 241250Z 27008KT 9999 FEW030 12/06 Q1018",
};

/* The clock's rates: stopped, real time, fast, backwards. */
static const double change_rates[] = { 0, 1, 60, 600, 3600, -3600 };

struct change_gen {
	uint64_t rng;
	int clock;		/* the clock's keys too (time, place, light modes) */
};

/* The seed: argv[i] when there, else $SKYD_TEST_SEED, else fallback. */
static inline uint64_t change_gen_seed(int argc, char **argv, int i, uint64_t fallback)
{
	const char *s = i < argc ? argv[i] : getenv("SKYD_TEST_SEED");

	return s && *s ? strtoull(s, NULL, 0) : fallback;
}

static inline double change_gen_uniform(struct change_gen *g, double lo, double hi)
{
	return lo + (hi - lo) * test_uniform(&g->rng);
}

static inline unsigned change_gen_below(struct change_gen *g, unsigned n)
{
	unsigned k = (unsigned)(test_uniform(&g->rng) * n);
	return k < n ? k : n - 1;
}

/* One key=value for a set, into buf. */
static inline void change_gen_pair(struct change_gen *g, char *buf, size_t size)
{
	const size_t n = sizeof(change_keys) / sizeof(change_keys[0]);
	const struct change_key *k;

	do
		k = &change_keys[change_gen_below(g, (unsigned)n)];
	while (k->clock && !g->clock);
	if (k->words && (k->lo == k->hi || change_gen_below(g, 4) == 0)) {
		unsigned m = 0;
		while (k->words[m])
			m++;
		snprintf(buf, size, "%s=%s", k->name, k->words[change_gen_below(g, m)]);
		return;
	}
	snprintf(buf, size, "%s=%.6g", k->name, change_gen_uniform(g, k->lo, k->hi));
}

/* "set" with one to three pairs (a key may come twice: the last wins). */
static inline void change_gen_set(struct change_gen *g, char *buf, size_t size)
{
	unsigned n = 1 + change_gen_below(g, 3);
	size_t o = (size_t)snprintf(buf, size, "set");

	for (unsigned i = 0; i < n && o < size; i++) {
		char pair[96];
		change_gen_pair(g, pair, sizeof(pair));
		o += (size_t)snprintf(buf + o, size - o, " %s", pair);
	}
}

/* "batch", two to four set lines and "end", one line each. */
static inline void change_gen_batch(struct change_gen *g, char *buf, size_t size)
{
	unsigned n = 2 + change_gen_below(g, 3);
	size_t o = (size_t)snprintf(buf, size, "batch");

	for (unsigned i = 0; i < n && o < size; i++) {
		char line[320];
		change_gen_set(g, line, sizeof(line));
		o += (size_t)snprintf(buf + o, size - o, "\n%s", line);
	}
	if (o < size)
		snprintf(buf + o, size - o, "\nend");
}

static inline void change_gen_metar(struct change_gen *g, char *buf, size_t size)
{
	const unsigned n = sizeof(change_metars) / sizeof(change_metars[0]);

	snprintf(buf, size, "set metar=\"%s\"", change_metars[change_gen_below(g, n)]);
}

/* A new rate for the clock, or (with the clock's keys) a new time. */
static inline void change_gen_clock(struct change_gen *g, char *buf, size_t size)
{
	const unsigned n = sizeof(change_rates) / sizeof(change_rates[0]);

	if (g->clock && change_gen_below(g, 3) == 0)
		snprintf(buf, size, "set utc=2026-%02u-%02uT%02u:%02u:00Z", 1 + change_gen_below(g, 12),
			 1 + change_gen_below(g, 28), change_gen_below(g, 24), change_gen_below(g, 60));
	else
		snprintf(buf, size, "set time_rate=%g", change_rates[change_gen_below(g, n)]);
}

#endif
