/* bench_accuracy_truth.c - the scenes of `skybench accuracy` and their ground
 * truth: the path tracer's radiance, cached by a hash of what it depends on. */
#include "bench_accuracy_internal.h"

#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "media.h"
#include "terrain.h"

/* Bumped whenever the path tracer's estimator or this file's use of it
 * changes, so that cached ground truth from before is never reused. */
#define GT_VERSION "gt2"

/* The direction set: every azimuth is covered by 0 to 180 degrees in steps
 * of 30 with the sun at 180, because the sky (the tables' and the
 * truth's) is symmetric about the sun's vertical plane; the directions
 * strictly between count twice. Elevations are denser near the horizon. */
static const double dir_elevations[] = { 0.5, 1, 1.5, 2, 2.5, 3, 4, 6, 9, 13, 20, 30, 45, 65 };
#define N_EL (sizeof(dir_elevations) / sizeof(dir_elevations[0]))
#define N_AZ 7
#define SUN_AZIMUTH_DEG 180.0

size_t acc_build_scenes(struct scene *sc, size_t max, bool reduced)
{
	static const double suns[] = { 90, 45, 20, 10, 5, 2, 0, -2, -4, -6 };
	static const double alts[] = { 0.2, 10 };
	static const double albedos[] = { 0, 0.3 };
	size_t n = 0;

#define ADD(...) do { if (n < max) sc[n++] = (struct scene){ __VA_ARGS__, .keys = { NULL }, .few = false }; } while (0)
#define SHADOWED(name_, alt, sun, down_, few_, ...)                                           \
	do {                                                                                  \
		if (n < max)                                                                  \
			sc[n++] = (struct scene){ .name = name_, .preset = "earth", .altitude_km = alt, \
						  .sun_elevation_deg = sun, .albedo = 0.3,        \
						  .scattering_scale = 1, .down = down_, .few = few_, \
						  .keys = { __VA_ARGS__ } };                      \
	} while (0)
#define BROKEN_SC "cloud1_oktas=6", "cloud1_base_m=1000", "cloud1_type=stratocumulus", "cloud_seed=1"
#define RIDGE "terrain=@ridge", "terrain_extent_km=40", "terrain_height_m=1500"
	if (reduced) {
		/* CI: a day sky with its horizon band and one twilight sky, */
		ADD("earth-s20-h0.2-a0.3", "earth", 0.2, 20, 0.3, 1, true, false, false);
		ADD("earth-s2-h0.2-a0.3", "earth", 0.2, 2, 0.3, 1, true, false, false);
		ADD("earth-s-4-h0.2-a0.3", "earth", 0.2, -4, 0.3, 1, true, false, false);
		/* and the atmospheres whose own terms only they switch on: the
		 * iteration (Earth x10), the shape and delta-M (Mars). */
		ADD("earth10x-s30-h0.2-a0.3", "earth", 0.2, 30, 0.3, 10, true, false, false);
		ADD("mars-s30-h0.2", "mars", 0.2, 30, -1, 1, true, false, false);
		ADD("mars-s5-h0.2", "mars", 0.2, 5, -1, 1, true, false, false);
		/* and two observers: 1 m over black ground, and 30 km looking
		 * up and down at the limb. */
		ADD("earth-s60-h0.001-a0", "earth", 0.001, 60, 0, 1, false, false, false);
		ADD("earth-s60-h30-a0", "earth", 30, 60, 0, 1, false, false, true);
		/* and two shadowed scenes on nine views each. */
		SHADOWED("shadow-ci-bkn-s30-h0.2", 0.2, 30, false, true, BROKEN_SC);
		SHADOWED("shadow-ci-ridge-s3-h0.2", 0.2, 3, false, true, RIDGE);
		return n;
	}
	for (size_t a = 0; a < 2; a++)
		for (size_t b = 0; b < 2; b++)
			for (size_t s = 0; s < sizeof(suns) / sizeof(suns[0]); s++) {
				char name[48];
				snprintf(name, sizeof(name), "earth-s%g-h%g-a%g", suns[s], alts[a], albedos[b]);
				bool main_row = a == 0 && b == 1;
				ADD("", "earth", alts[a], suns[s], albedos[b], 1, main_row,
				    main_row && (suns[s] == 20 || suns[s] == 2 || suns[s] == -2), false);
				snprintf(sc[n - 1].name, sizeof(sc[n - 1].name), "%s", name);
			}
	ADD("mars-s30-h0.2", "mars", 0.2, 30, -1, 1, true, false, false);
	ADD("mars-s5-h0.2", "mars", 0.2, 5, -1, 1, true, false, false);
	/* Not in the reduced matrix: a Mars sky that no constant was chosen
	 * by, to check one (PHASE_DELTA_ORDER). */
	ADD("mars-s15-h0.2", "mars", 0.2, 15, -1, 1, true, false, false);
	ADD("earth10x-s30-h0.2-a0.3", "earth", 0.2, 30, 0.3, 10, true, false, false);
	/* Observers from the ground to orbit over black ground, looking up
	 * while there is air above them and down at the limb: 1 m, a mountain,
	 * a balloon, the top of the atmosphere and the ISS. */
	static const double obs_alts[] = { 0.001, 2, 30, 100, 400 };
	static const double obs_suns[] = { 60, 10 };
	for (size_t a = 0; a < sizeof(obs_alts) / sizeof(obs_alts[0]); a++)
		for (size_t s = 0; s < sizeof(obs_suns) / sizeof(obs_suns[0]); s++) {
			char name[48];
			snprintf(name, sizeof(name), "earth-s%g-h%g-a0", obs_suns[s], obs_alts[a]);
			ADD("", "earth", obs_alts[a], obs_suns[s], 0, 1, false, false, obs_alts[a] > 1);
			snprintf(sc[n - 1].name, sizeof(sc[n - 1].name), "%s", name);
		}
	/* The shadowed scenes: the sun behind a broken layer (its seed puts
	 * the sun behind a cloud), a low sun through the gaps of scattered
	 * cumulus, an overcast at 300 m, a ridge's shadow at sunset, and an
	 * observer at 12 km over the broken layer, looking up and down. */
	SHADOWED("shadow-bkn-s30-h0.2", 0.2, 30, false, false, BROKEN_SC);
	SHADOWED("shadow-sct-cu-s5-h0.2", 0.2, 5, false, false, "cloud1_oktas=3.5", "cloud1_base_m=1000",
		 "cloud1_type=cumulus");
	SHADOWED("shadow-ovc300-s40-h0.2", 0.2, 40, false, false, "cloud1_oktas=8", "cloud1_base_m=300",
		 "cloud1_type=stratus");
	SHADOWED("shadow-ridge-s3-h0.2", 0.2, 3, false, false, RIDGE);
	SHADOWED("shadow-bkn-s30-h12", 12, 30, true, false, BROKEN_SC);
#undef ADD
#undef SHADOWED
#undef BROKEN_SC
#undef RIDGE
	return n;
}

static int apply(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		return -EINVAL;
	}
	return 0;
}

/* A scene's key; "terrain=@NAME" names a synthetic field (media.h). */
static int apply_scene_key(struct sky_state *s, const char *pair)
{
	char kv[512];
	const char *k = media_expand_key(pair, kv, sizeof(kv));
	if (!k) {
		fprintf(stderr, "skybench: %s: %s\n", pair, strerror(errno));
		return -EINVAL;
	}
	return apply(s, k);
}

/* The state of a scene under a configuration (NULL: the default preset). */
int acc_scene_state(const struct scene *sc, const struct config *cf, struct sky_state *ret)
{
	char kv[96];
	struct sky_state s;

	state_default(&s);
	snprintf(kv, sizeof(kv), "preset=%s", sc->preset);
	if (apply(&s, kv) < 0)
		return -EINVAL;
	s.altitude_km = sc->altitude_km;
	s.sun.elevation_deg = sc->sun_elevation_deg;
	s.sun.azimuth_deg = SUN_AZIMUTH_DEG;
	/* The truth has no night-sky floor; in daylight it is 1e-6 of the sky. */
	s.night.zenith_luminance_cd_m2 = 0.0;
	if (sc->albedo >= 0)
		for (int c = 0; c < 3; c++)
			s.atmo.ground_albedo[c] = sc->albedo;
	for (int i = 0; i < s.atmo.n_constituents; i++)
		for (int c = 0; c < 3; c++)
			s.atmo.c[i].scattering_per_km[c] *= sc->scattering_scale;
	for (int k = 0; cf && k < MAX_KEYS && cf->keys[k]; k++)
		if (apply(&s, cf->keys[k]) < 0)
			return -EINVAL;
	for (int k = 0; k < MAX_SCENE_KEYS && sc->keys[k]; k++)
		if (apply_scene_key(&s, sc->keys[k]) < 0)
			return -EINVAL;
	char err[256];
	if (state_validate(&s, 0, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s: %s\n", sc->name, err);
		return -EINVAL;
	}
	*ret = s;
	return 0;
}

/* Views down, for an observer above the ground: rays that graze the air
 * at these tangent altitudes (the limb), then rays this far below the
 * geometric horizon (the planet's disk, seen through the air), then the
 * nadir. */
static const double limb_tangent_km[] = { 80, 60, 40, 30, 20, 10, 5, 2, 0.5 };
static const double disk_below_deg[] = { 1, 5, 20 };

/* The set's ring at elevation el_deg: N_AZ azimuths, weighted. */
static void add_ring(struct gt *g, double el_deg)
{
	for (int a = 0; a < N_AZ && g->n < MAX_DIRS; a++) {
		g->dir[g->n] = (struct pt_dir){ el_deg, 30.0 * a };
		g->weight[g->n++] = a == 0 || a == N_AZ - 1 ? 1.0 : 2.0;
	}
}

/* Clouds and terrain break the mirror symmetry: the shadowed scenes'
 * views go round the whole circle, coarser, every one of weight 1. */
static const double shadow_elevations[] = { 2, 5, 10, 20, 40, 70 };
static const double few_elevations[] = { 5, 30 };
static const double shadow_tangent_km[] = { 5, 0.5 };
static const double shadow_below_deg[] = { 5, 20 };

static void add_circle(struct gt *g, double el_deg, int n_az)
{
	for (int a = 0; a < n_az && g->n < MAX_DIRS; a++) {
		g->dir[g->n] = (struct pt_dir){ el_deg, 360.0 * a / n_az };
		g->weight[g->n++] = 1.0;
	}
}

static void shadow_direction_set(const struct scene *sc, const struct sky_state *s, struct gt *g)
{
	int n_az = sc->few ? 4 : 8;
	size_t n_el = sc->few ? 2 : sizeof(shadow_elevations) / sizeof(shadow_elevations[0]);
	double rb = s->atmo.bottom_radius_km, r = rb + sc->altitude_km, deg = 180.0 / M_PI;

	for (size_t e = 0; e < n_el; e++)
		add_circle(g, sc->few ? few_elevations[e] : shadow_elevations[e], n_az);
	add_circle(g, 90.0, 1);
	if (!sc->down)
		return;
	for (size_t k = 0; k < 2; k++)
		if (shadow_tangent_km[k] < sc->altitude_km)
			add_circle(g, -acos((rb + shadow_tangent_km[k]) / r) * deg, n_az);
	for (size_t k = 0; k < 2; k++)
		add_circle(g, -(acos(rb / r) * deg + shadow_below_deg[k]), n_az);
	add_circle(g, -90.0, 1);
}

void acc_direction_set(const struct scene *sc, struct gt *g)
{
	struct sky_state s;
	g->n = 0;
	if (acc_scene_state(sc, NULL, &s) < 0)
		return;
	if (acc_shadowed(sc)) {
		shadow_direction_set(sc, &s, g);
		return;
	}
	double rb = s.atmo.bottom_radius_km, shell = s.atmo.top_radius_km - rb;
	/* Up only with at least 1 km of air above: from the top and beyond,
	 * tables and truth alike read 0 there, which would flatter the means. */
	if (sc->altitude_km < shell - 1.0) {
		for (size_t e = 0; e < N_EL; e++)
			add_ring(g, dir_elevations[e]);
		g->dir[g->n] = (struct pt_dir){ 90.0, 0.0 };
		g->weight[g->n++] = 1.0;
	}
	if (!sc->down)
		return;
	double r = rb + sc->altitude_km, deg = 180.0 / M_PI;
	for (size_t k = 0; k < sizeof(limb_tangent_km) / sizeof(limb_tangent_km[0]); k++)
		if (limb_tangent_km[k] < sc->altitude_km)
			add_ring(g, -acos((rb + limb_tangent_km[k]) / r) * deg);
	double dip_deg = acos(rb / r) * deg;
	for (size_t k = 0; k < sizeof(disk_below_deg) / sizeof(disk_below_deg[0]); k++)
		if (dip_deg + disk_below_deg[k] < 89.0)
			add_ring(g, -(dip_deg + disk_below_deg[k]));
	if (g->n < MAX_DIRS) {
		g->dir[g->n] = (struct pt_dir){ -90.0, 0.0 };
		g->weight[g->n++] = 1.0;
	}
}

/* FNV-1a, 64 bits. */
static uint64_t fnv(uint64_t h, const char *s)
{
	for (; *s; s++)
		h = (h ^ (unsigned char)*s) * 0x100000001b3ull;
	return h;
}

static uint64_t fnv_double(uint64_t h, double d)
{
	char buf[40];
	snprintf(buf, sizeof(buf), "%.17g;", d);
	return fnv(h, buf);
}

/* The clouds and terrain, only where there are some: the clear scenes'
 * hashes (and the committed truth) stay what they were. */
static uint64_t hash_media(uint64_t h, const struct sky_state *s)
{
	struct skycloudd_layer L[SKYCLOUD_MAX_LAYERS];
	double off[2];
	char buf[64];

	if (!media_present(s))
		return h;
	int n = state_cloud_layers_double(s, L);
	h = fnv(h, "media;");
	for (int i = 0; i < n; i++) {
		h = fnv_double(h, L[i].type);
		h = fnv_double(h, L[i].cover);
		h = fnv_double(h, L[i].base_km);
		h = fnv_double(h, L[i].top_km);
		h = fnv_double(h, L[i].seed);
		h = fnv_double(h, L[i].index);
	}
	state_cloud_offset_km(s, off);
	h = fnv_double(h, off[0]);
	h = fnv_double(h, off[1]);
	if (state_terrain_set(s)) {
		snprintf(buf, sizeof(buf), "%016llx;", (unsigned long long)s->terrain.hash);
		h = fnv(h, buf);
		h = fnv_double(h, s->terrain.extent_km);
		h = fnv_double(h, s->terrain.height_m);
	}
	return h;
}

/* Only what the truth depends on - the atmosphere, the observer's altitude
 * and the sun - so that keys added to the state later leave the cache (and
 * the committed truth of the CI test) valid. */
static uint64_t hash_scene(uint64_t h, const struct sky_state *s)
{
	const struct atmo *a = &s->atmo;
	h = fnv_double(h, a->bottom_radius_km);
	h = fnv_double(h, a->top_radius_km);
	for (int c = 0; c < 3; c++)
		h = fnv_double(h, a->ground_albedo[c]);
	h = fnv_double(h, a->n_constituents);
	for (int i = 0; i < a->n_constituents; i++) {
		const struct atmo_constituent *k = &a->c[i];
		for (int c = 0; c < 3; c++) {
			h = fnv_double(h, k->scattering_per_km[c]);
			h = fnv_double(h, k->absorption_per_km[c]);
		}
		h = fnv_double(h, k->phase);
		h = fnv_double(h, k->g);
		for (int l = 0; l < 2; l++) {
			const struct atmo_layer *y = &k->density.layers[l];
			h = fnv_double(h, y->width_km);
			h = fnv_double(h, y->exp_term);
			h = fnv_double(h, y->exp_scale_per_km);
			h = fnv_double(h, y->linear_per_km);
			h = fnv_double(h, y->constant);
		}
	}
	h = hash_media(h, s);
	h = fnv_double(h, s->altitude_km);
	h = fnv_double(h, s->sun.elevation_deg);
	h = fnv_double(h, s->sun.azimuth_deg);
	h = fnv_double(h, s->sun.angular_radius_deg);
	for (int c = 0; c < 3; c++)
		h = fnv_double(h, s->sun.illuminance_lx * s->sun.color[c]);
	return h;
}

static uint64_t gt_hash(const struct sky_state *s, const struct pt_options *po, const struct gt *g)
{
	struct { uint64_t h; } c = { 0xcbf29ce484222325ull };
	char buf[128];
	c.h = fnv(c.h, GT_VERSION);
	c.h = hash_scene(c.h, s);
	snprintf(buf, sizeof(buf), "err=%.9g;min=%llu;max=%llu;batch=%u;seed=%llu;n=%zu;", po->rel_error,
		 (unsigned long long)po->min_samples, (unsigned long long)po->max_samples, po->batch,
		 (unsigned long long)po->seed, g->n);
	c.h = fnv(c.h, buf);
	for (size_t i = 0; i < g->n; i++) {
		snprintf(buf, sizeof(buf), "%.9g:%.9g,", g->dir[i].elevation_deg, g->dir[i].azimuth_deg);
		c.h = fnv(c.h, buf);
	}
	return c.h;
}

static void fill_gt(struct gt *g, const struct pt_result *r)
{
	static const double w[3] = { 0.2126, 0.7152, 0.0722 };
	for (size_t i = 0; i < g->n; i++) {
		double v = 0;
		for (int c = 0; c < 3; c++) {
			g->rgb[i][c] = r[i].radiance[c];
			g->rgb_se[i][c] = r[i].std_error[c];
			v += w[c] * w[c] * r[i].std_error[c] * r[i].std_error[c];
		}
		g->lum[i] = luminance(g->rgb[i]);
		g->lum_se[i] = sqrt(v);	/* channels are traced with independent streams */
	}
}

static int gt_read(const char *path, struct gt *g)
{
	FILE *f = fopen(path, "re");
	if (!f)
		return -errno;
	static locale_t c_locale;
	if (!c_locale)
		c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	locale_t old = uselocale(c_locale);
	char line[512];
	size_t i = 0;
	struct pt_result r[1];
	int rc = 0;
	static struct pt_result all[MAX_DIRS];
	while (fgets(line, sizeof(line), f)) {
		if (line[0] == '#')
			continue;
		double el, az;
		unsigned long long n;
		if (i >= g->n || sscanf(line, "%lf %lf %lf %lf %lf %lf %lf %lf %llu", &el, &az,
					 &r->radiance[0], &r->radiance[1], &r->radiance[2],
					 &r->std_error[0], &r->std_error[1], &r->std_error[2], &n) != 9 ||
		    fabs(el - g->dir[i].elevation_deg) > 1e-6 || fabs(az - g->dir[i].azimuth_deg) > 1e-6) {
			rc = -EPROTO;
			break;
		}
		all[i++] = r[0];
	}
	uselocale(old);
	fclose(f);
	if (rc == 0 && i != g->n)
		rc = -EPROTO;
	if (rc == 0)
		fill_gt(g, all);
	return rc;
}

static int gt_write(const char *path, const char *what, const struct gt *g, const struct pt_result *r)
{
	char tmp[4096];
	if (!FITS(tmp, "%s.tmp", path))
		return -ENAMETOOLONG;
	FILE *f = fopen(tmp, "we");
	if (!f)
		return -errno;
	static locale_t c_locale;
	if (!c_locale)
		c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	locale_t old = uselocale(c_locale);
	fprintf(f, "# skybench accuracy ground truth (%s), %s\n"
		   "# elevation_deg azimuth_deg L_r L_g L_b se_r se_g se_b samples\n", GT_VERSION, what);
	for (size_t i = 0; i < g->n; i++)
		fprintf(f, "%.9g %.9g %.17g %.17g %.17g %.9g %.9g %.9g %llu\n", g->dir[i].elevation_deg,
			g->dir[i].azimuth_deg, r[i].radiance[0], r[i].radiance[1], r[i].radiance[2],
			r[i].std_error[0], r[i].std_error[1], r[i].std_error[2],
			(unsigned long long)r[i].samples);
	uselocale(old);
	int rc = ferror(f) ? -EIO : 0;
	if (fclose(f) != 0 && rc == 0)
		rc = -errno;
	if (rc == 0 && rename(tmp, path) < 0)
		rc = -errno;
	if (rc < 0)
		unlink(tmp);
	return rc;
}

/* The share of each view's single scattering that the scene shadows, for
 * the categories (not cached: seconds a scene). */
static int shadow_fractions(const struct scene *sc, const struct sky_state *s,
			    const struct pt_sun *sun, const struct media *md, struct gt *g)
{
	for (size_t i = 0; i < g->n; i++) {
		g->shadow[i] = 0.0;
		if (acc_shadowed(sc) &&
		    pt_shadow_fraction(&s->atmo, s->altitude_km, sun, &md->scene, &g->dir[i],
				       &g->shadow[i]) < 0)
			return -EINVAL;
	}
	return 0;
}

/* The truth of g from the read-only cache, the cache, or the tracer (then
 * cached). */
static int trace(const struct opts *o, const struct scene *sc, const struct sky_state *s,
		 const struct pt_sun *sun, const struct media *md, const struct pt_options *po,
		 uint64_t h, const char *kind, double rel_error, struct gt *g)
{
	char path[4096], what[256];
	if (o->cache_ro) {
		if (FITS(path, "%s/gt-%016llx.txt", o->cache_ro, (unsigned long long)h) &&
		    gt_read(path, g) == 0)
			return 0;
	}
	if (!FITS(path, "%s/gt-%016llx.txt", o->cache, (unsigned long long)h))
		return -ENAMETOOLONG;
	if (gt_read(path, g) == 0)
		return 0;
	struct pt_result *r = calloc(g->n, sizeof(*r));
	if (!r)
		return -ENOMEM;
	int rc = pt_render_scene(&s->atmo, s->altitude_km, sun, acc_shadowed(sc) ? &md->scene : NULL,
				 g->dir, g->n, po, r);
	if (rc == 0) {
		fill_gt(g, r);
		if (!FITS(what, "%s %s, rel_error %g, max_samples %llu", sc->name, kind, rel_error,
			  (unsigned long long)o->max_samples))
			what[sizeof(what) - 1] = 0;
		int wr = gt_write(path, what, g, r);
		if (wr < 0)
			fprintf(stderr, "skybench: cannot write '%s': %s\n", path, strerror(-wr));
	} else {
		fprintf(stderr, "skybench: path tracer on %s: %s\n", sc->name, strerror(-rc));
	}
	free(r);
	return rc;
}

/* The ground truth for g's directions: from the read-only cache, the cache,
 * or the path tracer (then written to the cache). */
int acc_ground_truth(const struct opts *o, const struct scene *sc, double rel_error, struct gt *g,
		     const char *kind)
{
	struct sky_state s;
	struct pt_options po;

	if (acc_scene_state(sc, NULL, &s) < 0)
		return -EINVAL;
	pt_options_default(&po);
	po.rel_error = rel_error;
	po.max_samples = o->max_samples;
	po.threads = o->threads;
	uint64_t h = gt_hash(&s, &po, g);
	if (o->list_truth) {
		printf("%s %s gt-%016llx.txt\n", sc->name, kind, (unsigned long long)h);
		return 0;
	}
	struct pt_sun sun = { .elevation_deg = s.sun.elevation_deg, .azimuth_deg = s.sun.azimuth_deg,
			      .angular_radius_deg = s.sun.angular_radius_deg };
	for (int c = 0; c < 3; c++)
		sun.illuminance[c] = s.sun.illuminance_lx * s.sun.color[c];
	struct media md;
	char err[256];
	if (media_from_state(&s, &md, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s: %s\n", sc->name, err);
		return -EINVAL;
	}
	int rc = shadow_fractions(sc, &s, &sun, &md, g);
	if (rc == 0)
		rc = trace(o, sc, &s, &sun, &md, &po, h, kind, rel_error, g);
	media_finish(&md);
	return rc;
}
