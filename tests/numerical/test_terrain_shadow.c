/* test_terrain_shadow.c - the terrain as a caster in the shadow maps
 * (docs/terrain.md, "On the device"), on the device: a north-south ridge
 * 2 km high, 3 km east of the observer, with the sun 5 degrees up in the
 * east behind it, under a thin cirrus and alone (the maps exist for the
 * terrain without a layer, and then no coverage table):
 *  - every texel's opaque depth (the map's 4th channel) is where
 *    skyterrain_ray_hit finds the same ray's first point below the
 *    ground, within the march's bracket: shadow.comp steps half a texel
 *    across the ground and returns the far end of the bracket after three
 *    secant steps, so its depth is at most one step beyond the crossing
 *    (the step along the ray: half a texel over the ray's horizontal
 *    share) and never before it, less float rounding at the map plane's
 *    distance; a ray that only grazes a crest can be missed by either
 *    march, so a few texels may disagree about hitting at all;
 *  - the aerial perspective and sky-view with the ridge are never
 *    brighter than without it, and the aerial in-scatter at 5 km is
 *    below the unshadowed one. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "eng.h"
#include "skymap.h"
#include "skyterrain.h"
#include "state_geom.h"
#include "terrain.h"
#include "sky_probe.h"
#include "test.h"
#include "vk_or_skip.h"

#define RIDGE_TEXELS 64
#define RIDGE_EXTENT_KM 20.0

static struct eng *eng;
static char ridge_path[600];

/* A SKYTERRAIN16 file: a Gaussian ridge along x = 3 km, 1 km wide. */
static int write_ridge(void)
{
	const char *tmp = getenv("TMPDIR");
	char dir[512];
	snprintf(dir, sizeof(dir), "%s/test_terrain_shadow.XXXXXX", tmp && *tmp ? tmp : "/tmp");
	if (!mkdtemp(dir))
		return -1;
	snprintf(ridge_path, sizeof(ridge_path), "%s/ridge.raw", dir);
	FILE *f = fopen(ridge_path, "wb");
	if (!f)
		return -1;
	fprintf(f, "SKYTERRAIN16 %d %d\n", RIDGE_TEXELS, RIDGE_TEXELS);
	for (int j = 0; j < RIDGE_TEXELS; j++)
		for (int i = 0; i < RIDGE_TEXELS; i++) {
			double x = ((i + 0.5) / RIDGE_TEXELS - 0.5) * RIDGE_EXTENT_KM;
			uint16_t v = (uint16_t)lrint(0.8 * 65535.0 * exp(-(x - 3.0) * (x - 3.0)));
			unsigned char b[2] = { (unsigned char)(v & 255), (unsigned char)(v >> 8) };
			fwrite(b, 1, 2, f);
		}
	return fclose(f);
}

/* The sun's map's 4th channel against skyterrain_ray_hit, ray by ray. */
static void depths_match(const char *pairs)
{
	struct sky_state s;
	struct eng_timing t;
	struct state_lights lights;
	struct terrain *field = NULL;
	struct skyterrain view;
	float frames[2][16];
	char err[512];

	if (probe_state_of(pairs, &s) < 0)
		return;
	CHECK(eng_compute(eng, &s, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	size_t bytes = 0;
	const float *map = eng_cloud_table(eng, STATE_CLOUD_SHADOW, &bytes);
	CHECK(map != NULL);
	if (!map || state_terrain_get(&s, &field, &view, err, sizeof(err)) < 0) {
		FAIL("%s", err);
		return;
	}
	state_lights_of(&s, &lights);
	eng_cloud_frames(&s, &lights, frames);
	const float *u = frames[0], *v = frames[0] + 4, *l = frames[0] + 8, *sc = frames[0] + 12;
	unsigned w = s.quality.shadow_width, hits = 0, both = 0, disagree = 0;
	double worst = 0.0, rb = s.atmo.bottom_radius_km;
	double horizontal = sqrt(l[0] * l[0] + l[1] * l[1]);
	double step_km = 0.5 * RIDGE_EXTENT_KM / RIDGE_TEXELS / horizontal;
	for (unsigned y = 0; y < w; y++)
		for (unsigned x = 0; x < w; x++) {
			float o[3], d[3], hit_km = 0.0f;
			for (int k = 0; k < 3; k++) {
				o[k] = (u[3] + (x + 0.5f) / sc[0]) * u[k] + (v[3] + (y + 0.5f) / sc[1]) * v[k] +
				       l[3] * l[k];
				d[k] = -l[k];
			}
			int hit = skyterrain_ray_hit(&view, (float)rb, o, d, 1e6f, &hit_km);
			float depth = map[((size_t)y * w + x) * 4 + 3];
			bool gpu_hit = depth < 1e29f;
			hits += hit;
			if (hit != gpu_hit) {
				disagree++;
				continue;
			}
			if (!hit)
				continue;
			both++;
			double err_km = depth - hit_km;
			worst = fmax(worst, fabs(err_km));
			if (!(err_km >= -1e-3 && err_km <= step_km + 1e-3))
				FAIL("texel %u %u: depth %.6f km, skyterrain_ray_hit %.6f km", x, y, depth, hit_km);
		}
	printf("%u of %u rays meet the ridge, %u disagree about it; worst depth %.4f km (step %.4f km)\n", hits,
	       w * w, disagree, worst, step_km);
	CHECK(hits > w);
	CHECK(disagree * 100 <= hits);
	terrain_unref(field);
}

/* The aerial perspective's mean RGB over the slice nearest depth_km. */
static double aerial_mean_at(const struct sky_state *s, const float *aerial, double depth_km)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	bool sq = s->quality.aerial_spacing == STATE_SQUARED;
	unsigned best = 0;
	for (unsigned k = 0; k < q->depth; k++)
		if (fabs(skymap_aerial_depth_km(k, q->depth, s->quality.aerial_range_km, sq) - depth_km) <
		    fabs(skymap_aerial_depth_km(best, q->depth, s->quality.aerial_range_km, sq) - depth_km))
			best = k;
	size_t texels = (size_t)q->width * q->height;
	double sum = 0;
	for (size_t i = 0; i < texels * 3; i++)
		sum += aerial[(best * texels + i / 3) * 4 + i % 3];
	return sum / (3.0 * texels);
}

/* Sky-view and aerial of pairs as floats (malloc'd). */
static int tables_of(const char *pairs, struct sky_state *s, float *ret[2], size_t ret_n[2])
{
	double ms;

	if (probe_state_of(pairs, s) < 0 || probe_sky_aerial(eng, s, ret, ret_n, &ms) < 0)
		return -1;
	printf("%s: %.1f ms\n", pairs, ms);
	return 0;
}

static void never_brighter(const char *open, const char *shadowed)
{
	float *a[2] = { 0 }, *b[2] = { 0 };
	size_t n[2], m[2];
	struct sky_state s;

	if (tables_of(open, &s, a, n) == 0 && tables_of(shadowed, &s, b, m) == 0) {
		for (int k = 0; k < 2; k++) {
			size_t darker = 0;
			CHECK_EQ(n[k], m[k]);
			for (size_t i = 0; i < n[k] && n[k] == m[k]; i++) {
				if (i % 4 == 3)
					continue;
				darker += b[k][i] < a[k][i];
				if (!(b[k][i] <= a[k][i]))
					FAIL("%s value %zu: %.9g above the open %.9g", k ? "aerial" : "skyview", i,
					     b[k][i], a[k][i]);
			}
			printf("%-8s %zu of %zu values darker with the ridge\n", k ? "aerial" : "skyview", darker,
			       n[k] / 4 * 3);
		}
		double lit = aerial_mean_at(&s, a[1], 5.0), dark = aerial_mean_at(&s, b[1], 5.0);
		printf("aerial in-scatter at 5 km: open %.6g, behind the ridge %.6g, ratio %.4f\n", lit, dark,
		       dark / lit);
		CHECK(lit > 0.0 && dark < lit);
	}
	for (int k = 0; k < 2; k++) {
		free(a[k]);
		free(b[k]);
	}
}

int main(void)
{
	char open[256], shadowed[1024];

	eng = vk_or_skip();
	CHECK(write_ridge() == 0);
	snprintf(open, sizeof(open), "sun_elevation_deg=5 sun_azimuth_deg=90 cloud1_oktas=1 "
		 "cloud1_base_m=9000 cloud1_type=cirrus");
	snprintf(shadowed, sizeof(shadowed), "%s terrain=%s terrain_extent_km=%g terrain_height_m=2500", open,
		 ridge_path, RIDGE_EXTENT_KM);
	depths_match(shadowed);
	never_brighter(open, shadowed);
	/* The ridge alone: the maps exist for it, without a coverage table. */
	snprintf(open, sizeof(open), "sun_elevation_deg=5 sun_azimuth_deg=90");
	snprintf(shadowed, sizeof(shadowed), "%s terrain=%s terrain_extent_km=%g terrain_height_m=2500", open,
		 ridge_path, RIDGE_EXTENT_KM);
	depths_match(shadowed);
	CHECK(eng_cloud_table(eng, STATE_CLOUD_COVERAGE, NULL) == NULL);
	never_brighter(open, shadowed);
	eng_free(eng);
	unlink(ridge_path);
	*strrchr(ridge_path, '/') = '\0';
	rmdir(ridge_path);
	return test_report("test_terrain_shadow");
}
