/* stab_clouds.c - the stiff and extreme cases of the clouds and the terrain
 * (stab.h) and their invariants on the model side: the field of
 * proto/skycloud.h and proto/skyterrain.h in double and the path tracer;
 * and the check that any two sets of tables, with the scene and without
 * it over a white ground, keep the shadowed never brighter than the bound
 * (the engine's cloud passes run the same cases through it). */
#include "stab.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>

#include "media.h"
#include "pt.h"

const struct stab_cloud_case stab_cloud_cases[] = {
	{ "overcast 8/8 at 100 m", "an optically thick sheet (tau 31) 100 m up, sun 30",
	  { "cloud1_oktas=8", "cloud1_base_m=100", "cloud1_type=stratus", "sun_elevation_deg=30" }, 0 },
	{ "cumulonimbus to 12 km", "a tower of optical depth up to 400, its anvil, sun 20",
	  { "cloud1_oktas=6", "cloud1_base_m=800", "cloud1_top_m=12000", "cloud1_type=cumulonimbus",
	    "sun_elevation_deg=20" }, 0 },
	{ "layer below a flight at 10 km", "the observer above a broken layer, looking down on it",
	  { "altitude_km=10", "cloud1_oktas=7", "cloud1_base_m=1000", "cloud1_type=stratocumulus",
	    "camera_pitch_deg=-30", "sun_elevation_deg=25" }, 0 },
	{ "sun on the horizon through a layer", "light rays that graze a cumulus layer for 100 km",
	  { "sun_elevation_deg=0", "cloud1_oktas=4", "cloud1_base_m=1000", "cloud1_type=cumulus" }, 0 },
	{ "terrain cliff at the observer's feet", "an opaque face 16 m away, 500 m high, the sun behind it",
	  { "terrain=@cliff", "terrain_extent_km=2", "terrain_height_m=500", "altitude_km=0.001",
	    "sun_elevation_deg=10", "sun_azimuth_deg=90" }, 0 },
	{ "cloud keys at their lows", "a 1 m layer on the ground at 0.001 oktas, a 1 km region, 16-texel tables",
	  { "cloud1_oktas=0.001", "cloud1_base_m=0", "cloud1_top_m=1", "cloud1_type=stratus",
	    "cloud_seed=0", "cloud_extent_km=1", "wind_dir_deg=0", "wind_speed_mps=0",
	    "cloud_width=16", "shadow_width=16", "cloud_cell_texels=0" }, 0 },
	{ "cloud keys at their highs", "four overcast layers from the ground to 20 km, the largest seed, wind and tables, placed in 2100",
	  { "cloud1_oktas=8", "cloud1_base_m=0", "cloud1_type=cirrus", "cloud2_oktas=8",
	    "cloud2_base_m=5000", "cloud2_type=altostratus", "cloud3_oktas=8", "cloud3_base_m=10000",
	    "cloud3_type=cumulonimbus", "cloud4_oktas=8", "cloud4_base_m=19999",
	    "cloud4_top_m=20000", "cloud4_type=cumulus", "cloud_seed=4294967295",
	    "wind_dir_deg=360", "wind_speed_mps=150", "cloud_extent_km=512", "cloud_width=2048",
	    "shadow_width=2048", "cloud_cell_texels=64" },
	  4102444800.0 },
	{ "terrain keys at their highs", "a ridge 20 km high over 1024 km, sun 3",
	  { "terrain=@ridge", "terrain_extent_km=1024", "terrain_height_m=20000",
	    "sun_elevation_deg=3" }, 0 },
	{ "terrain keys at their lows", "a ridge of height 0 over 10 m",
	  { "terrain=@ridge", "terrain_extent_km=0.01", "terrain_height_m=0" }, 0 },
};
const size_t stab_n_cloud_cases = sizeof(stab_cloud_cases) / sizeof(stab_cloud_cases[0]);

int stab_cloud_state(const struct stab_cloud_case *c, struct sky_state *ret, char *err,
		     size_t err_size)
{
	struct sky_state s;
	char pair[400];

	state_default(&s);
	for (int k = 0; k < STAB_CLOUD_KEYS && c->keys[k]; k++) {
		const char *kv = media_expand_key(c->keys[k], pair, sizeof(pair));
		if (!kv) {
			snprintf(err, err_size, "%s: %s", c->keys[k], strerror(errno));
			return -EIO;
		}
		int r = state_set_pair(&s, kv, NULL, err, err_size);
		if (r < 0)
			return r;
	}
	if (c->utc_s > 0.0)
		s.clouds.utc_s = c->utc_s;
	stab_medium(&s);
	int r = state_validate(&s, 0, err, err_size);
	if (r < 0)
		return r;
	*ret = s;
	return 0;
}

void stab_cloud_bound(const struct sky_state *s, struct sky_state *ret)
{
	char err[256];
	*ret = *s;
	for (int i = 0; i < STATE_CLOUD_LAYERS; i++)
		ret->clouds.layer[i].oktas = NAN;
	state_set(ret, "terrain", "none", NULL, err, sizeof(err));
	state_set(ret, "ground_albedo", "1", NULL, err, sizeof(err));
}

/* ---- the field ---- */

static uint64_t fnv_double(uint64_t h, double v)
{
	uint64_t u;
	memcpy(&u, &v, sizeof(u));
	for (int i = 0; i < 8; i++)
		h = (h ^ ((u >> (8 * i)) & 0xffu)) * 0x100000001b3ull;
	return h;
}

/* A grid through every layer: 24 x 24 columns over the region, 16 heights
 * from a tenth of a thickness under the base to a tenth over the top. */
struct grid {
	const struct skycloudd_layer *layers;
	int n;
	double extent_km, offset_km[2];
	uint64_t checksum;
	struct stab_result *r;	/* NULL: only the checksum */
	const char *name;
};

static void *walk_grid(void *arg)
{
	struct grid *g = arg;
	uint64_t h = 0xcbf29ce484222325ull;

	for (int l = 0; l < g->n; l++) {
		const struct skycloudd_layer *L = &g->layers[l];
		double thick = L->top_km - L->base_km;
		for (int j = 0; j < 24; j++)
			for (int i = 0; i < 24; i++)
				for (int k = 0; k < 16; k++) {
					double x = g->extent_km * (-1.0 + (i + 0.5) / 12.0);
					double y = g->extent_km * (-1.0 + (j + 0.5) / 12.0);
					double z = L->base_km + thick * (-0.1 + 1.2 * (k + 0.5) / 16.0);
					double d = skycloudd_density(L, x, y, z, g->offset_km);
					h = fnv_double(h, d);
					if (!g->r)
						continue;
					stab_note(g->r, STAB_FINITE, isfinite(d),
						  "%s: layer %d density at (%g, %g, %g) km is %g", g->name, l, x, y, z, d);
					stab_note(g->r, STAB_T_RANGE, d >= 0.0 && d <= L->extinction_per_km,
						  "%s: layer %d density %.9g at (%g, %g, %g) km outside [0, %g]",
						  g->name, l, d, x, y, z, L->extinction_per_km);
				}
	}
	g->checksum = h;
	return NULL;
}

/* The light the layers let through toward the sun from points above the
 * site, the sky's occlusion at every height, the terrain's heights. */
static void check_light(const char *name, const struct sky_state *s, const struct media *md,
			struct stab_result *r)
{
	const struct pt_scene *sc = &md->scene;
	double rb = s->atmo.bottom_radius_km, el = s->sun.elevation_deg * M_PI / 180.0;
	double az = s->sun.azimuth_deg * M_PI / 180.0;
	double d[3] = { cos(el) * sin(az), cos(el) * cos(az), sin(el) };

	for (int k = 0; k <= 40; k++) {
		double h = 0.5 * k, o[3] = { 0.0, 0.0, h };
		double tau = skycloudd_optical_depth(sc->layers, sc->n_layers, sc->offset_km, rb, o, d,
						     1e4, 256);
		double occ = skycloudd_sky_occlusion(sc->layers, sc->n_layers, h);
		stab_note(r, STAB_FINITE, isfinite(tau) && isfinite(occ),
			  "%s: at %g km optical depth %g, occlusion %g", name, h, tau, occ);
		stab_note(r, STAB_T_RANGE, tau >= 0.0 && exp(-tau) <= 1.0 && occ >= 0.0 && occ <= 1.0,
			  "%s: at %g km optical depth %.9g, occlusion %.9g", name, h, tau, occ);
	}
	if (!sc->terrain)
		return;
	for (int j = 0; j < 32; j++)
		for (int i = 0; i < 32; i++) {
			double e = sc->terrain->extent_km, x = e * ((i + 0.5) / 32 - 0.5);
			double y = e * ((j + 0.5) / 32 - 0.5), hz = skyterraind_height_km(sc->terrain, x, y);
			stab_note(r, STAB_T_RANGE, isfinite(hz) && hz >= 0.0 && hz <= sc->terrain->height_km,
				  "%s: terrain at (%g, %g) km is %.9g km", name, x, y, hz);
		}
}

/* Views up and down: the air's single scattering with the scene never
 * above the clear sky's; the tracer's radiance finite and >= 0, the same
 * bits on one thread and on three. */
static int check_views(const char *name, const struct sky_state *s, const struct media *md,
		       struct stab_result *r)
{
	static const struct pt_dir dirs[] = { { 90, 0 }, { 30, 0 }, { 10, 90 }, { 3, 180 },
					      { 1, 270 }, { -5, 0 }, { -30, 180 }, { -90, 0 } };
	enum { N = sizeof(dirs) / sizeof(dirs[0]) };
	struct pt_sun sun = { .elevation_deg = s->sun.elevation_deg, .azimuth_deg = s->sun.azimuth_deg,
			      .angular_radius_deg = s->sun.angular_radius_deg };
	struct pt_result a[N], b[N];
	struct pt_options o;

	for (int c = 0; c < 3; c++)
		sun.illuminance[c] = s->sun.illuminance_lx * s->sun.color[c];
	for (int i = 0; i < N; i++) {
		double clear[3], shaded[3];
		if (pt_shadow_pair(&s->atmo, s->altitude_km, &sun, &md->scene, &dirs[i], clear, shaded) < 0)
			return -EINVAL;
		for (int ch = 0; ch < 3; ch++)
			stab_note(r, STAB_SHADOWED, isfinite(shaded[ch]) && shaded[ch] >= 0.0 &&
						       shaded[ch] <= clear[ch] * (1.0 + 1e-12),
				  "%s: view %g/%g ch %d: single scattering %.9g with the scene, %.9g without",
				  name, dirs[i].elevation_deg, dirs[i].azimuth_deg, ch, shaded[ch], clear[ch]);
	}
	pt_options_default(&o);
	o.rel_error = 0.0;
	o.min_samples = o.max_samples = o.batch = 64;
	o.threads = 1;
	int rc = pt_render_scene(&s->atmo, s->altitude_km, &sun, &md->scene, dirs, N, &o, a);
	o.threads = 3;
	if (rc == 0)
		rc = pt_render_scene(&s->atmo, s->altitude_km, &sun, &md->scene, dirs, N, &o, b);
	if (rc < 0)
		return rc;
	stab_note(r, STAB_FIELD_SAME, memcmp(a, b, sizeof(a)) == 0,
		  "%s: the tracer on one thread and on three differs", name);
	for (int i = 0; i < N; i++)
		for (int ch = 0; ch < 3; ch++) {
			double v = a[i].radiance[ch];
			stab_note(r, STAB_FINITE, isfinite(v), "%s: traced view %g/%g ch %d is %g", name,
				  dirs[i].elevation_deg, dirs[i].azimuth_deg, ch, v);
			stab_note(r, STAB_NONNEG, !(v < 0.0), "%s: traced view %g/%g ch %d is %g", name,
				  dirs[i].elevation_deg, dirs[i].azimuth_deg, ch, v);
		}
	return 0;
}

int stab_cloud_check_model(const char *name, const struct sky_state *s, struct stab_result *r,
			   uint64_t *ret_checksum, char *err, size_t err_size)
{
	struct media md;
	int rc = media_from_state(s, &md, err, err_size);

	if (rc < 0)
		return rc;
	struct grid here = { .layers = md.scene.layers, .n = md.scene.n_layers,
			     .extent_km = state_cloud_extent_km(s), .r = r, .name = name };
	memcpy(here.offset_km, md.scene.offset_km, sizeof(here.offset_km));
	struct grid there = here;
	there.r = NULL;
	pthread_t t;
	int started = pthread_create(&t, NULL, walk_grid, &there) == 0;
	walk_grid(&here);
	if (started)
		pthread_join(t, NULL);
	else
		walk_grid(&there);
	stab_note(r, STAB_FIELD_SAME, here.checksum == there.checksum,
		  "%s: the field's checksum %016llx here, %016llx in another thread", name,
		  (unsigned long long)here.checksum, (unsigned long long)there.checksum);
	check_light(name, s, &md, r);
	rc = check_views(name, s, &md, r);
	if (rc < 0)
		snprintf(err, err_size, "%s: the path tracer: %s", name, strerror(-rc));
	media_finish(&md);
	*ret_checksum = here.checksum;
	return rc;
}

/* ---- the tables ---- */

void stab_check_shadowed(const char *name, const struct model_tables *with,
			 const struct model_tables *without, const struct stab_tol *tol,
			 struct stab_result *r)
{
	for (int t = STATE_SKYVIEW; t <= STATE_AERIAL; t++) {
		const double *a = with->t[t], *b = without->t[t];
		if (!a || !b)
			continue;
		size_t n = (size_t)with->w[t] * with->h[t] * with->d[t] * 4;
		double peak = 0.0;
		for (size_t i = 0; i < n; i++)
			if (i % 4 != 3 && isfinite(b[i]))
				peak = fmax(peak, b[i]);
		for (size_t i = 0; i < n; i++) {
			if (i % 4 == 3)
				continue;
			stab_note(r, STAB_SHADOWED, isfinite(a[i]) && !(a[i] > b[i] + tol->abs_t * peak),
				  "%s: %s texel %zu ch %zu: %.9g with the scene, %.9g without", name,
				  state_table_names[t], i / 4, i % 4, a[i], b[i]);
		}
	}
}
