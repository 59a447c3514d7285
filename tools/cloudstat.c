/* cloudstat.c - the statistics of the cloud field of proto/skycloud.h: the
 * coverage fBm's quantile table (skycloud_quantile, printed as C with
 * --table), its mean and spread, the detail noise's distribution, and the
 * covered fraction of a whole period against the cover for 1 to 8 oktas.
 * docs/clouds.md quotes its output.
 *   usage: cloudstat [--table] [--seeds N] */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "skycloud.h"

/* Samples per axis of a period: a prime, so that the samples fall at every
 * fraction of the lattice's cells. */
#define GRID 1021
#define BINS 400000
#define LO (-2.0)
#define HI 2.0

struct hist {
	unsigned long long n[BINS];
	unsigned long long total;
	double sum, sum2, min, max;
};

static void hist_add(struct hist *h, double v)
{
	long b = (long)((v - LO) / (HI - LO) * BINS);
	b = b < 0 ? 0 : b >= BINS ? BINS - 1 : b;
	h->n[b]++;
	h->total++;
	h->sum += v;
	h->sum2 += v * v;
	h->min = v < h->min ? v : h->min;
	h->max = v > h->max ? v : h->max;
}

/* The value below which a fraction u lies, linear inside a bin. */
static double hist_quantile(const struct hist *h, double u)
{
	if (u <= 0.0)
		return h->min;
	if (u >= 1.0)
		return h->max;
	double want = u * (double)h->total, below = 0.0;
	for (long b = 0; b < BINS; b++) {
		if (below + (double)h->n[b] >= want) {
			double f = h->n[b] ? (want - below) / (double)h->n[b] : 0.0;
			return LO + (b + f) * (HI - LO) / BINS;
		}
		below += (double)h->n[b];
	}
	return h->max;
}

/* The fraction of the samples below v. */
static double hist_quantile_below(const struct hist *h, double v)
{
	long end = (long)((v - LO) / (HI - LO) * BINS);
	unsigned long long below = 0;
	for (long b = 0; b < end && b < BINS; b++)
		below += h->n[b];
	return (double)below / (double)h->total;
}

int main(int argc, char **argv)
{
	int table = 0, seeds = 8;
	for (int i = 1; i < argc; i++) {
		if (strcmp(argv[i], "--table") == 0)
			table = 1;
		else if (strcmp(argv[i], "--seeds") == 0 && i + 1 < argc)
			seeds = atoi(argv[++i]);
		else {
			fprintf(stderr, "usage: cloudstat [--table] [--seeds N]\n");
			return 2;
		}
	}
	struct hist *h = calloc(1, sizeof(*h)), *dh = calloc(1, sizeof(*dh));
	if (!h || !dh)
		return 1;
	h->min = dh->min = 1e30;
	h->max = dh->max = -1e30;
	const double step = (double)SKYCLOUD_PERIOD_KM / GRID;
	for (int s = 0; s < seeds; s++)
		for (uint32_t layer = 0; layer < SKYCLOUD_MAX_LAYERS; layer++) {
			/* Cumulus cells (2 km): the distribution does not depend on the
			 * scale, only the lattice's; its finest octave stays coarser
			 * than the grid's step. */
			struct skycloud_layer L;
			skycloud_layer_init(&L, SKYCLOUD_STRATOCUMULUS, 0.5, 1.0, 1.4,
					    (uint32_t)s * 2654435761u, layer);
			for (int j = 0; j < GRID; j++)
				for (int i = 0; i < GRID; i++) {
					float x = (float)(i * step), y = (float)(j * step);
					hist_add(h, skycloud_coverage_fbm(&L, x, y));
					if (layer == 0 && (i & 3) == 0 && (j & 3) == 0)
						hist_add(dh, skycloud_detail(&L, x, y,
									     (float)(1.0 + 0.37 * ((i + j) & 7))));
				}
		}
	double mean = h->sum / (double)h->total;
	double sd = sqrt(h->sum2 / (double)h->total - mean * mean);
	if (table) {
		printf("static const double skycloud_quantile[SKYCLOUD_QUANTILES + 1] = {\n");
		for (int k = 0; k <= SKYCLOUD_QUANTILES; k++)
			printf("%s%.6f,%s", k % 6 == 0 ? "\t" : " ",
			       hist_quantile(h, (double)k / SKYCLOUD_QUANTILES),
			       k % 6 == 5 || k == SKYCLOUD_QUANTILES ? "\n" : "");
		printf("};\n");
		return 0;
	}
	printf("coverage fBm: %llu samples, mean %.5f, sd %.5f, min %.4f, max %.4f\n", h->total,
	       mean, sd, h->min, h->max);
	for (int k = 1; k <= 7; k++) {
		double u = k / 8.0, q = hist_quantile(h, u);
		/* What a normal law of the same mean and spread puts below q. */
		double z = (q - mean) / sd;
		printf("  quantile %.3f: %+.5f (normal law: %.4f below)\n", u, q,
		       0.5 * erfc(-z / sqrt(2.0)));
	}
	double dmean = dh->sum / (double)dh->total;
	printf("detail: %llu samples, mean %.4f, sd %.4f, min %.4f, max %.4f, median %.4f, "
	       "saturated %.4f\n", dh->total, dmean,
	       sqrt(dh->sum2 / (double)dh->total - dmean * dmean), dh->min, dh->max,
	       hist_quantile(dh, 0.5), 1.0 - hist_quantile_below(dh, 1.0));
	free(h);
	free(dh);
	return 0;
}
