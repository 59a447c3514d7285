/* fuzz_metar.c - libFuzzer target for the METAR decoder (weather/metar.c)
 * as skyd reaches it from set metar="..." and the config file: the input
 * is one report, decoded, described and mapped onto the weather inputs,
 * then applied to a default state and checked as skyd checks a change.
 * Built without libFuzzer, a main() replays the files named on the command
 * line (fuzz_replay.h). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "metar.h"
#include "state.h"

/* What describe hands out is read, so that no read is optimised out. */
static volatile size_t sink;
static volatile double oktas;

static void emit(void *ctx, const char *key, const char *value)
{
	sink += strlen(key) + strlen(value);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static struct sky_state base;
	static int ready;
	char text[METAR_MAX_LEN + 64], err[256];
	struct metar m;
	struct weather w;

	if (!ready) {
		state_default(&base);
		ready = 1;
	}
	/* The report as a C string, as the protocol's parser hands it on:
	 * cut at the first NUL, at most a little over the decoder's bound. */
	if (size >= sizeof(text))
		size = sizeof(text) - 1;
	memcpy(text, data, size);
	text[size] = 0;
	if (metar_decode(text, &m, err, sizeof(err)) == 0) {
		oktas = metar_oktas(&m);	/* NAN: no cloud group */
		weather_init(&w);
		metar_weather(&m, &w);
		sink += (size_t)weather_validate(&w, err, sizeof(err));
		metar_describe(&m, emit, NULL);
	}
	struct sky_state s = base;
	uint32_t dirty = 0;
	if (state_set_metar(&s, text, &m, &dirty, err, sizeof(err)) == 0)
		state_validate(&s, 0, err, sizeof(err));
	return 0;
}

#include "fuzz_replay.h"
