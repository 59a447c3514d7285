/* astrobench.c - how many sun and moon positions (and sun-time days) one core computes per second. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "astro.h"

#define RUN_S 1.0	/* wall time per measurement */

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* The "model name" line of /proc/cpuinfo, or "unknown CPU". */
static void cpu_name(char *buf, size_t size)
{
	char line[512];
	FILE *f = fopen("/proc/cpuinfo", "re");

	snprintf(buf, size, "unknown CPU");
	if (!f)
		return;
	while (fgets(line, sizeof(line), f)) {
		char *colon = strchr(line, ':');
		if (strncmp(line, "model name", 10) == 0 && colon) {
			colon += 1 + (colon[1] == ' ');
			colon[strcspn(colon, "\n")] = '\0';
			snprintf(buf, size, "%s", colon);
			break;
		}
	}
	fclose(f);
}

enum what { SUN, MOON, SUN_TIMES };

/* Evaluations per second over RUN_S, on times that step 37 minutes apart
 * so that no two calls see the same input. sink keeps the work alive. */
static double measure(enum what w, double *sink)
{
	struct astro_site site = { 39.742476, -105.1786, 1830.14 };
	struct astro_options o;
	char err[256];
	long n = 0;
	double t0 = now_s(), t = t0, utc_s = 1.7e9;

	astro_options_default(&o);
	while (t - t0 < RUN_S) {
		for (int i = 0; i < 256; i++, n++) {
			int r;
			utc_s += 37.0 * 60.0;
			if (w == SUN) {
				struct astro_sun s;
				r = astro_sun(&site, utc_s, &o, &s, err, sizeof(err));
				*sink += s.apparent.zenith_deg;
			} else if (w == MOON) {
				struct astro_moon m;
				r = astro_moon(&site, utc_s, &o, &m, err, sizeof(err));
				*sink += m.illuminance_lx;
			} else {
				struct astro_times tt;
				struct astro_date d = { 2026, 1 + (int)(n % 12), 1 + (int)(n % 28), -420 };
				r = astro_sun_times(&site, &d, &o, &tt, err, sizeof(err));
				*sink += tt.transit_utc_s;
			}
			if (r < 0) {
				fprintf(stderr, "astrobench: %s\n", err);
				return -1.0;
			}
		}
		t = now_s();
	}
	return (double)n / (t - t0);
}

int main(void)
{
	char cpu[256];
	double sink = 0.0;

	cpu_name(cpu, sizeof(cpu));
	double sun = measure(SUN, &sink);
	double moon = measure(MOON, &sink);
	double days = measure(SUN_TIMES, &sink);
	if (sun < 0 || moon < 0 || days < 0)
		return 1;
	printf("cpu: %s (one thread)\n", cpu);
	printf("astro_sun:       %10.0f evaluations/s (%.2f us each)\n", sun, 1e6 / sun);
	printf("astro_moon:      %10.0f evaluations/s (%.2f us each)\n", moon, 1e6 / moon);
	printf("astro_sun_times: %10.0f days/s (%.2f us each)\n", days, 1e6 / days);
	printf("(checksum %g)\n", sink);
	return 0;
}
