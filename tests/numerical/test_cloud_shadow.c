/* test_cloud_shadow.c - the cloud layers' shadows in the tables
 * (docs/clouds.md, "In the tables"), on the device:
 *  - under an 8/8 stratocumulus at 1.0-1.4 km with the sun at 40 degrees,
 *    the aerial perspective's in-scattered light at 10 km is below the
 *    clear sky's but far from dark: the sun's single scattering under the
 *    layer passes a column of optical depth ~9 (its beam, the forward
 *    peak kept, exp(-(1 - g^2) 9.3 / 0.77) ~ 0.03), but a
 *    conservative slab lets the light through diffusely (two-stream,
 *    tau 9.3, g 0.85: 1 - R = 0.52 of the sun's flux, 0.034 of it in the
 *    delta-scaled beam exp(-(1 - g^2) tau / mu),
 *    1 / (1 + 3/4 (1 - g) tau) = 0.49 of the sky's), and the ground
 *    reflects part of it back: the air under the base gets between half
 *    and 0.9 of the clear sky's light (measured 0.726 on lavapipe); the
 *    whole slice, whose views that look up reach the air over the deck,
 *    lit from below by its reflection, between 0.6 and 1 (measured
 *    0.841; docs/clouds.md, "In the tables").
 *  - the layers never add more light than a white ground would: every
 *    texel of sky-view and aerial with layers is at most the same sky's
 *    without them over a ground of albedo 1 (the deck reflects and
 *    transmits what reaches it, R + T <= 1; the shadows only take away),
 *    for an overcast, a broken layer at low sun and a layer below an
 *    observer in flight. The clear sky over its own ground is no bound:
 *    the air over a deck is brighter than over the ground, as the path
 *    tracer's is (docs/findings/shaders.md,
 *    "The shadowed scenes against the tracer").
 *  - the moon's map: with the sun 30 degrees down and the moon up and lit
 *    under the overcast, the moon's map (z = 1) holds the layer over most
 *    of its texels (those whose ray crosses the region: 62 % on lavapipe)
 *    and the moonlight in the aerial perspective under the base (what
 *    the moon adds to the same sky without it, whose own 3.5e-5 no layer
 *    changes) drops as the sunlight does, to the same bounds (0.5 to 0.9;
 *    measured 0.746); with the moon down
 *    (no illuminance, as the clock gives it below
 *    DRIVE_MOON_MIN_ELEVATION_DEG) its frame is zero and its slice reads
 *    zeros while the sun's slice changes, whatever it held before, so
 *    that two engines (two hosts) hold the same bits: the one that made
 *    the moonless tables ahead into its spare set as the one that made
 *    them over its moonlit ones.
 *  - the wind within a cell of the tables' lattice: the maps made at the
 *    lattice point and read shifted by the field's move give sky-view and
 *    aerial perspective closer to those of maps made where the field is
 *    (cloud_cell_texels=0) than the same maps read where they were made
 *    (docs/clouds.md, "The wind between the tables").
 *  - a light that moves within its map's cell keeps the maps, and sky-view
 *    reads the light they let through at its steps as kept: the same bits
 *    as a fresh engine's, the sun alone and with the moon lit; the wind's
 *    shift within the tables' cell reads the maps elsewhere, and the kept
 *    light is not read.
 *  - the cloud tables made ahead (eng_submit_ahead) for a light in the
 *    next cell of its grid leave the bound tables as they were; the change
 *    that reaches that cell takes them without a cloud pass, and its
 *    sky-view, aerial perspective and cloud tables are a fresh engine's
 *    bits; the tables it left are taken back when the light returns.
 *  - ice and water: each phase's beam takes its own 1 - g^2, so a
 *    stratus beside a thin cirrus, above it or around it, reads as beside
 *    a like altostratus but for that layer's own light (mixed_phases).
 *  - a clear sky runs no cloud pass: no cloud table, no shadow map.
 *  - the cloud and shadow tables are the same bits from a second engine,
 *    also where that engine had another field and only the maps are asked
 *    for (their coverage table comes along). */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "eng.h"
#include "skymap.h"
#include "state_geom.h"
#include "sky_probe.h"
#include "test.h"
#include "vk_or_skip.h"

static struct eng *eng;

/* Sky-view and aerial perspective of s as floats (malloc'd). */
static int tables_of_state(const struct sky_state *s, float *ret[2], size_t ret_n[2])
{
	return probe_sky_aerial(eng, s, ret, ret_n, NULL);
}

/* The same of pairs. */
static int tables_of(const char *pairs, float *ret[2], size_t ret_n[2])
{
	struct sky_state s;

	return probe_state_of(pairs, &s) < 0 ? -1 : tables_of_state(&s, ret, ret_n);
}

/* Every radiance value of the cloudy tables at most the bound's (the
 * same sky clear over a white ground). */
static void never_brighter(const char *bound, const char *cloudy)
{
	float *a[2] = { 0 }, *b[2] = { 0 };
	size_t n[2], m[2];

	if (tables_of(bound, a, n) == 0 && tables_of(cloudy, b, m) == 0)
		for (int k = 0; k < 2; k++) {
			size_t darker = 0;
			CHECK_EQ(n[k], m[k]);
			for (size_t i = 0; i < n[k] && n[k] == m[k]; i++) {
				if (i % 4 == 3)
					continue;
				darker += b[k][i] < a[k][i];
				if (!(b[k][i] <= a[k][i]))
					FAIL("%s: %s value %zu: %.9g above the bound %.9g", cloudy,
					     k ? "aerial" : "skyview", i, b[k][i], a[k][i]);
			}
			printf("%-60s %-8s %zu of %zu values darker\n", cloudy, k ? "aerial" : "skyview", darker,
			       n[k] / 4 * 3);
		}
	for (int k = 0; k < 2; k++) {
		free(a[k]);
		free(b[k]);
	}
}

/* Whether aerial texel (x, y) of the state's camera looks along a ray
 * whose point at depth_km lies below base_km (aerial.comp's directions). */
static bool below(const struct sky_state *s, unsigned x, unsigned y, double depth_km, double base_km)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	double f[3], r[3], u[3], d[3], n = 0.0;
	double th = tan(0.5 * s->camera.vfov_deg * M_PI / 180.0);
	double nx = (x + 0.5) / q->width * 2.0 - 1.0, ny = (y + 0.5) / q->height * 2.0 - 1.0;

	state_camera_basis(&s->camera, f, r, u);
	for (int i = 0; i < 3; i++) {
		d[i] = f[i] + nx * th * s->camera.aspect * r[i] + ny * th * u[i];
		n += d[i] * d[i];
	}
	double z = s->altitude_km + depth_km * d[2] / sqrt(n) -
		   depth_km * depth_km / (2.0 * s->atmo.bottom_radius_km);
	return z < base_km;
}

/* The mean in-scattered luminance-ish (mean RGB) of the aerial slice
 * nearest depth_km, over its texels whose point there lies below
 * below_km (1e30: all). */
static double aerial_mean_at(const struct sky_state *s, const float *aerial, double depth_km,
			     double below_km)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	unsigned best = 0;
	for (unsigned k = 0; k < q->depth; k++)
		if (fabs(skymap_aerial_depth_km(k, q->depth, s->quality.aerial_range_km,
						s->quality.aerial_spacing == STATE_SQUARED) - depth_km) <
		    fabs(skymap_aerial_depth_km(best, q->depth, s->quality.aerial_range_km,
						s->quality.aerial_spacing == STATE_SQUARED) - depth_km))
			best = k;
	double sum = 0;
	size_t texels = (size_t)q->width * q->height, n = 0;
	for (size_t i = 0; i < texels; i++) {
		if (!below(s, (unsigned)(i % q->width), (unsigned)(i / q->width), depth_km, below_km))
			continue;
		n++;
		for (int c = 0; c < 3; c++)
			sum += aerial[(best * texels + i) * 4 + c];
	}
	return n ? sum / (3.0 * n) : 0.0;
}

static void overcast_at_ten_km(void)
{
	const char *clear = "sun_elevation_deg=40", *cloudy =
		"sun_elevation_deg=40 cloud1_oktas=8 cloud1_base_m=1000";
	float *a[2] = { 0 }, *b[2] = { 0 };
	size_t n[2], m[2];
	struct sky_state s;

	if (probe_state_of(clear, &s) == 0 && tables_of(clear, a, n) == 0 && tables_of(cloudy, b, m) == 0) {
		double lit = aerial_mean_at(&s, a[1], 10.0, 1e30), shadowed = aerial_mean_at(&s, b[1], 10.0, 1e30);
		printf("aerial in-scatter at 10 km, sun 40 deg: clear %.6g, under 8/8 at 1 km %.6g, ratio %.4f\n",
		       lit, shadowed, shadowed / lit);
		CHECK(lit > 0.0 && shadowed / lit > 0.6 && shadowed / lit < 1.0);
		/* The views that stay under the base for their 10 km: the
		 * light the layer lets through diffusely, and the ground's. */
		lit = aerial_mean_at(&s, a[1], 10.0, 1.0);
		shadowed = aerial_mean_at(&s, b[1], 10.0, 1.0);
		printf("the same, views under the base all the way: clear %.6g, overcast %.6g, ratio %.3g\n", lit,
		       shadowed, shadowed / lit);
		CHECK(lit > 0.0 && shadowed / lit > 0.5 && shadowed / lit < 0.9);
	}
	for (int k = 0; k < 2; k++) {
		free(a[k]);
		free(b[k]);
	}
}

/* The moon's map under the overcast: computed and darkening while the
 * moon lights, left alone while it does not. */
static void moon_map(void)
{
	const char *clear = "sun_elevation_deg=-30 moon_elevation_deg=40 moon_azimuth_deg=200 "
			    "moon_illuminance_lx=0.25";
	const char *moonless = "sun_elevation_deg=-30 moon_illuminance_lx=0";
	char cloudy[256], down[256];
	float *a[2] = { 0 }, *b[2] = { 0 }, *c[2] = { 0 };
	size_t n[2], m[2], bytes = 0;
	struct sky_state s;
	struct state_lights lights;
	struct eng_timing t;
	float frames[2][16];
	char err[512];

	snprintf(cloudy, sizeof(cloudy), "%s cloud1_oktas=8 cloud1_base_m=1000", clear);
	if (probe_state_of(cloudy, &s) < 0 || tables_of(moonless, c, n) < 0 || tables_of(clear, a, n) < 0 ||
	    tables_of(cloudy, b, m) < 0)
		goto out;
	const float *map = eng_cloud_table(eng, STATE_CLOUD_SHADOW, &bytes);
	size_t w = s.quality.shadow_width, slice = w * w * 4, covered = 0;
	CHECK(map != NULL && bytes == 2 * slice * sizeof(float));
	if (!map || bytes != 2 * slice * sizeof(float))
		goto out;
	for (size_t i = 0; i < w * w; i++)
		covered += map[slice + 4 * i + 2] > 0.0f;
	printf("moon's map under 8/8: %zu of %zu texels with cloud\n", covered, w * w);
	CHECK(covered > w * w / 2);
	double night = aerial_mean_at(&s, c[1], 10.0, 1.0);
	double lit = aerial_mean_at(&s, a[1], 10.0, 1.0) - night;
	double shadowed = aerial_mean_at(&s, b[1], 10.0, 1.0) - night;
	printf("moonlight in the aerial in-scatter at 10 km under the base: clear %.6g, overcast %.6g, "
	       "ratio %.3g (without the moon %.6g)\n", lit, shadowed, shadowed / lit, night);
	/* The sun's bounds under the base: the same slab, lit by the moon. */
	CHECK(lit > 0.0 && shadowed / lit > 0.5 && shadowed / lit < 0.9);

	/* The moon down: a new field, the sun's slice new, the moon's
	 * zeros. */
	float *moon = malloc(2 * slice * sizeof(float));
	snprintf(down, sizeof(down),
		 "sun_elevation_deg=30 moon_elevation_deg=-20 moon_azimuth_deg=200 moon_illuminance_lx=0 "
		 "cloud1_oktas=8 cloud1_base_m=1000 cloud_seed=9");
	if (!moon || probe_state_of(down, &s) < 0) {
		free(moon);
		goto out;
	}
	memcpy(moon, map, 2 * slice * sizeof(float));
	CHECK(eng_compute(eng, &s, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	state_lights_of(&s, &lights);
	eng_cloud_frames(&s, &lights, frames);
	for (int i = 0; i < 16; i++)
		CHECK(frames[1][i] == 0.0f);
	map = eng_cloud_table(eng, STATE_CLOUD_SHADOW, NULL);
	CHECK(map != NULL);
	if (map) {
		size_t nonzero = 0;
		CHECK(memcmp(map, moon, slice * sizeof(float)) != 0);
		for (size_t i = slice; i < 2 * slice; i++)
			nonzero += map[i] != 0.0f;
		CHECK_EQ(nonzero, 0u);
	}
	free(moon);
out:
	for (int k = 0; k < 2; k++) {
		free(a[k]);
		free(b[k]);
		free(c[k]);
	}
}

/* A clear sky makes no cloud table; a cloudy one makes both, the same
 * bits on a second engine. */
/* The sum of |a - b| over the radiance of n floats (RGBA), over that of
 * |b|. */
static double rel_l1(const float *a, const float *b, size_t n)
{
	double d = 0.0, m = 0.0;
	for (size_t i = 0; i < n; i++)
		if (i % 4 != 3) {
			d += fabs((double)a[i] - b[i]);
			m += fabs((double)b[i]);
		}
	return m > 0.0 ? d / m : 0.0;
}

static void kept_maps_read_shifted(void)
{
	struct sky_state kept, fresh, unshifted;
	float *a[2] = { 0 }, *b[2] = { 0 }, *c[2] = { 0 };
	size_t n[2], m[2], l[2];

	/* Low sun from the west over broken cumulus: shafts across the sky.
	 * Maps that resolve the cumulus' cells (200 m texels), and a cell of
	 * eight texels, so that the shift is far more than what the grid's
	 * sampling of the field moves. */
	if (probe_state_of("sun_elevation_deg=6 sun_azimuth_deg=270 cloud1_oktas=4 cloud1_base_m=1200 "
			   "cloud1_type=cumulus cloud_extent_km=50 shadow_width=512 cloud_width=512 "
			   "cloud_cell_texels=8", &kept) < 0)
		return;
	double cell_km = kept.quality.cloud_cell_texels * 2.0 * state_cloud_extent_km(&kept) / 512.0;
	CHECK(cell_km > 0.0);
	/* 0.9 of a cell past a lattice point: the maps made there. */
	kept.clouds.offset_km[0] = 40.0 * cell_km + 0.9 * cell_km;
	kept.clouds.offset_km[1] = 3.0 * cell_km + 0.5 * cell_km;
	fresh = kept;
	fresh.quality.cloud_cell_texels = 0.0;
	/* What the kept maps give read where they were made: the field at
	 * the lattice point. */
	unshifted = kept;
	unshifted.clouds.offset_km[0] = 40.0 * cell_km;
	unshifted.clouds.offset_km[1] = 3.0 * cell_km;
	if (tables_of_state(&kept, a, n) == 0 && tables_of_state(&fresh, b, m) == 0 &&
	    tables_of_state(&unshifted, c, l) == 0)
		for (int k = 0; k < 2; k++) {
			CHECK(n[k] == m[k] && n[k] == l[k]);
			double shifted = rel_l1(a[k], b[k], n[k]), still = rel_l1(c[k], b[k], n[k]);
			printf("wind 0.9 cell (%.2f km) past the maps: %s off the fresh maps' by %.2e shifted, "
			       "%.2e read where made\n", cell_km, k ? "aerial" : "skyview", shifted, still);
			/* What is left is the maps' own sampling: a fresh map samples
			 * the field's shadow at other points than the kept one, and
			 * bilinear reads of sharp edges differ (0.74 and 0.28 of the
			 * unshifted difference on lavapipe). The maps read where
			 * they were made, or shifted the wrong way (1.17 and 0.98),
			 * fail. */
			CHECK(still > 1e-3);
			CHECK(shifted < 0.85 * still);
		}
	for (int k = 0; k < 2; k++) {
		free(a[k]);
		free(b[k]);
		free(c[k]);
	}
}

/* Ice and water (docs/clouds.md, "In the tables"): a thin stratus (tau
 * about 3) under 2 % of a high layer at 8.5-10 km, or with 2 % of a layer
 * at 0.9-1.2 km around it, either a cirrus (ice) or an altostratus
 * (water), so that the region, the casters' top and the light's cell are
 * the same. Each phase's beam is scaled by its own 1 - g^2 (the map keeps
 * the ice's depth), so the stratus' beam is the same beside either: the
 * tables differ by the second layer's own light alone (on lavapipe, sky-
 * view and aerial: 1.9 % and 2.0 % above, 0.33 % and 0.28 % around),
 * where the larger 1 - g^2 for all, the ice's, darkened the stratus'
 * beam beside the cirrus (4.2 % and 4.6 %, 2.4 % and 2.4 %). */
static void mixed_phases(void)
{
	const char *second[] = { "cloud2_base_m=8500 cloud2_top_m=10000", "cloud2_base_m=900 cloud2_top_m=1200" };
	for (int j = 0; j < 2; j++) {
		char ice[512], alto[512];
		const char *water = "sun_elevation_deg=50 cloud_extent_km=160 cloud1_oktas=8 cloud1_base_m=1000 "
				    "cloud1_top_m=1050 cloud1_type=stratus cloud2_fraction=0.02";
		snprintf(ice, sizeof(ice), "%s %s cloud2_type=cirrus", water, second[j]);
		snprintf(alto, sizeof(alto), "%s %s cloud2_type=altostratus", water, second[j]);
		float *a[2] = { 0 }, *b[2] = { 0 };
		size_t n[2], m[2];
		if (tables_of(ice, a, n) == 0 && tables_of(alto, b, m) == 0)
			for (int k = 0; k < 2; k++) {
				CHECK(n[k] == m[k]);
				double d = rel_l1(a[k], b[k], n[k]);
				printf("stratus with 2 %% of cirrus against altostratus %s: %s %.2e\n",
				       j ? "around it" : "above it", k ? "aerial" : "skyview", d);
				CHECK(d < (j ? 0.01 : 0.03));
			}
		for (int k = 0; k < 2; k++) {
			free(a[k]);
			free(b[k]);
		}
	}
}

/* Table t of eng and of other: the same bits. */
static void same_table(struct eng *other, int t)
{
	size_t a_bytes = 0, b_bytes = 0;
	const void *a = t < STATE_N_TABLES ? eng_table(eng, (enum state_table)t, &a_bytes)
					   : eng_cloud_table(eng, t, &a_bytes);
	const void *b = t < STATE_N_TABLES ? eng_table(other, (enum state_table)t, &b_bytes)
					   : eng_cloud_table(other, t, &b_bytes);

	CHECK(a && b && a_bytes == b_bytes && a_bytes > 16);
	if (a && b && a_bytes == b_bytes)
		CHECK(memcmp(a, b, a_bytes) == 0);
}

/* Sky-view of s from a fresh engine and from eng, which computed the
 * state before; kept: whether eng's read its light as kept. */
static void skyview_as_fresh(const struct sky_state *s, int kept)
{
	struct eng_timing t;
	char err[512];

	CHECK(eng_compute(eng, s, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.skyview_light_kept, kept);
	CHECK_EQ(t.computed & STATE_BIT(STATE_CLOUD_SHADOW), 0u);
	struct eng *fresh = vk_or_skip();
	CHECK(eng_compute(fresh, s, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.skyview_light_kept, 0);
	same_table(fresh, STATE_SKYVIEW);
	eng_free(fresh);
}

static void kept_light_bits(void)
{
	static const char *const lights[] = { "", "moon_elevation_deg=40 moon_azimuth_deg=200 moon_illuminance_lx=0.25 " };
	static const char *const suns[] = { "20", "20.05", "20" };
	const char *layers = "cloud1_oktas=5 cloud1_base_m=1000 cloud2_oktas=3 cloud2_base_m=4000 "
			     "cloud2_type=altostratus";
	struct eng_timing t;
	struct sky_state s;
	char pairs[512], err[512];

	for (int i = 0; i < 2; i++) {
		/* 20 and 20.05 degrees: one cell of the sun's grid (a cell is
		 * about 1.3 degrees of elevation here). The first computation
		 * keeps nothing (the field's standing is not known yet), the
		 * second keeps the light, the third reads it. */
		for (int k = 0; k < 3; k++) {
			snprintf(pairs, sizeof(pairs), "sun_elevation_deg=%s %s%s", suns[k], lights[i], layers);
			if (probe_state_of(pairs, &s) < 0)
				return;
			if (k < 2) {
				CHECK(eng_compute(eng, &s, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
				CHECK_EQ(t.skyview_light_kept, 0);
			} else {
				skyview_as_fresh(&s, 1);
			}
		}
		/* The wind a tenth of a coverage texel on: the maps kept, read
		 * shifted, the kept light not read. */
		s.clouds.offset_km[0] += 0.2;
		skyview_as_fresh(&s, 0);
	}
}

/* The states of "lead layers" for each of the two leads; -1 when one is
 * refused. */
static int two_states(const char *const lead[2], const char *layers, struct sky_state ret[2])
{
	char pairs[512];

	for (int k = 0; k < 2; k++) {
		snprintf(pairs, sizeof(pairs), "%s %s", lead[k], layers);
		if (probe_state_of(pairs, &ret[k]) < 0)
			return -1;
	}
	return 0;
}

static void made_ahead(void)
{
	static const int tables[] = { STATE_SKYVIEW, STATE_AERIAL, STATE_CLOUD_COVERAGE, STATE_CLOUD_SHADOW };
	const char *layers = "moon_elevation_deg=40 moon_azimuth_deg=200 moon_illuminance_lx=0.25 "
			     "cloud1_oktas=5 cloud1_base_m=1000 cloud2_oktas=3 cloud2_base_m=4000 "
			     "cloud2_type=altostratus";
	const uint32_t lit = STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL);
	/* 20 and 22 degrees: the next cell of the sun's grid but one (a
	 * cell is about 1.3 degrees of elevation here). */
	static const char *const suns[2] = { "sun_elevation_deg=20", "sun_elevation_deg=22" };
	struct sky_state two[2];
	struct eng_timing t;
	char err[512];
	size_t bytes = 0;

	if (two_states(suns, layers, two) < 0)
		return;
	const struct sky_state *now = &two[0], *next = &two[1];
	CHECK(eng_compute(eng, now, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	const void *shadow = eng_cloud_table(eng, STATE_CLOUD_SHADOW, &bytes);
	void *before = shadow ? malloc(bytes) : NULL;
	CHECK(before != NULL);
	if (!before)
		return;
	memcpy(before, shadow, bytes);
	CHECK_EQ(eng_clouds_made(eng, now, NULL), ENG_CLOUDS_BOUND);
	CHECK_EQ(eng_clouds_made(eng, next, NULL), ENG_CLOUDS_NONE);
	CHECK_EQ(eng_submit_ahead(eng, next, NULL, err, sizeof(err)), 0);
	CHECK(eng_wait(eng, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.computed & STATE_BIT(STATE_CLOUD_SHADOW), (uint32_t)STATE_BIT(STATE_CLOUD_SHADOW));
	CHECK_EQ(t.computed & lit, 0u);
	CHECK_EQ(eng_clouds_made(eng, next, NULL), ENG_CLOUDS_AHEAD);
	CHECK_EQ(eng_submit_ahead(eng, next, NULL, err, sizeof(err)), 1);
	/* The bound tables are the last computation's still. */
	shadow = eng_cloud_table(eng, STATE_CLOUD_SHADOW, &bytes);
	CHECK(shadow && memcmp(shadow, before, bytes) == 0);
	free(before);

	CHECK(eng_compute(eng, next, lit, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.clouds_ahead, 1);
	CHECK_EQ(t.computed & STATE_CLOUD_TABLES, 0u);
	struct eng *fresh = vk_or_skip();
	CHECK(eng_compute(fresh, next, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	for (size_t i = 0; i < sizeof(tables) / sizeof(tables[0]); i++)
		same_table(fresh, tables[i]);
	/* Back: the tables the swap left are taken again. */
	CHECK_EQ(eng_clouds_made(eng, now, NULL), ENG_CLOUDS_AHEAD);
	CHECK(eng_compute(eng, now, lit, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.clouds_ahead, 1);
	CHECK(eng_compute(fresh, now, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	for (size_t i = 0; i < sizeof(tables) / sizeof(tables[0]); i++)
		same_table(fresh, tables[i]);
	eng_free(fresh);
}

/* The moon lit, then unlit one cell of the sun's grid on: the tables of
 * the second state made in place over the moonlit ones, and on a second
 * engine made ahead into its spare set, are the same bits, the moon's
 * slice included. */
static void unlit_moon_ahead(void)
{
	static const int tables[] = { STATE_SKYVIEW, STATE_AERIAL, STATE_CLOUD_COVERAGE, STATE_CLOUD_SHADOW };
	const char *layers = "moon_elevation_deg=40 moon_azimuth_deg=200 cloud1_oktas=5 cloud1_base_m=1000 "
			     "cloud2_oktas=3 cloud2_base_m=4000 cloud2_type=altostratus";
	const uint32_t lit = STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL);
	static const char *const moons[2] = { "sun_elevation_deg=20 moon_illuminance_lx=0.25",
					      "sun_elevation_deg=22 moon_illuminance_lx=0" };
	struct sky_state two[2];
	struct eng_timing t;
	char err[512];

	if (two_states(moons, layers, two) < 0)
		return;
	const struct sky_state *moonlit = &two[0], *moonless = &two[1];
	CHECK(eng_compute(eng, moonlit, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK(eng_compute(eng, moonless, lit, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.clouds_ahead, 0);
	struct eng *ahead = vk_or_skip();
	CHECK(eng_compute(ahead, moonlit, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK_EQ(eng_submit_ahead(ahead, moonless, NULL, err, sizeof(err)), 0);
	CHECK(eng_wait(ahead, &t, err, sizeof(err)) == 0);
	CHECK(eng_compute(ahead, moonless, lit, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.clouds_ahead, 1);
	for (size_t i = 0; i < sizeof(tables) / sizeof(tables[0]); i++)
		same_table(ahead, tables[i]);
	eng_free(ahead);
}

static void demand_and_bits(void)
{
	struct sky_state clear, cloudy;
	struct eng_timing t;
	char err[512];

	if (probe_state_of("sun_elevation_deg=10", &clear) < 0 ||
	    probe_state_of("sun_elevation_deg=10 cloud1_oktas=5 cloud1_base_m=1500 cloud1_type=cumulus "
		     "wind_speed_mps=10 cloud_seed=7", &cloudy) < 0)
		return;
	CHECK(eng_compute(eng, &clear, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK(eng_cloud_table(eng, STATE_CLOUD_COVERAGE, NULL) == NULL);
	CHECK(eng_cloud_table(eng, STATE_CLOUD_SHADOW, NULL) == NULL);
	CHECK_EQ(t.computed & STATE_CLOUD_TABLES, 0u);
	CHECK(eng_compute(eng, &cloudy, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.computed & STATE_CLOUD_TABLES, (uint32_t)STATE_CLOUD_TABLES);
	/* The second engine had another field, and only the maps are asked
	 * for: they are made from the new field's coverage table, which
	 * comes along. */
	struct eng *other = vk_or_skip();
	struct sky_state seed8 = cloudy;
	seed8.clouds.seed = 8;
	CHECK(eng_compute(other, &seed8, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK(eng_compute(other, &cloudy, STATE_BIT(STATE_CLOUD_SHADOW), &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.computed & STATE_CLOUD_TABLES, (uint32_t)STATE_CLOUD_TABLES);
	for (int k = STATE_CLOUD_COVERAGE; k <= STATE_CLOUD_SHADOW; k++)
		same_table(other, k);
	eng_free(other);
	/* Back to clear: the tables go. */
	CHECK(eng_compute(eng, &clear, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK(eng_cloud_table(eng, STATE_CLOUD_COVERAGE, NULL) == NULL);
}

int main(void)
{
	eng = vk_or_skip();
	overcast_at_ten_km();
	never_brighter("sun_elevation_deg=40 ground_albedo=1",
		       "sun_elevation_deg=40 cloud1_oktas=8 cloud1_base_m=1000");
	never_brighter("sun_elevation_deg=4 sun_azimuth_deg=250 ground_albedo=1",
		       "sun_elevation_deg=4 sun_azimuth_deg=250 cloud1_oktas=4 cloud1_base_m=1200 "
		       "cloud1_type=cumulus");
	never_brighter("altitude_km=6 sun_elevation_deg=20 ground_albedo=1",
		       "altitude_km=6 sun_elevation_deg=20 cloud1_oktas=6 cloud1_base_m=1000");
	moon_map();
	kept_maps_read_shifted();
	kept_light_bits();
	made_ahead();
	unlit_moon_ahead();
	mixed_phases();
	demand_and_bits();
	eng_free(eng);
	return test_report("test_cloud_shadow");
}
