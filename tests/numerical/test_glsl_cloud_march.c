/* test_glsl_cloud_march.c - proto/glsl/skycloud_march.glsl against
 * proto/skycloudmarch.h: the view march, the shadow on a point and the
 * compositing run on the Vulkan device (lavapipe here) for the same
 * scenes, tables and rays as the C, which computes the tables (a coverage
 * table, a Beer shadow map) and checks the device's answers.
 *
 * Four scenes: a broken stratocumulus at noon read from the coverage table
 * and the shadow map; cumulus under cirrus at a low sun with the field's
 * own coverage and a light march; an overcast stratus seen from above; four
 * layers with a cumulonimbus. Rays from the observer in every direction,
 * stopped by a scene depth one time in eight, 16 to 64 steps, any jitter.
 * Twice: the shader filtering the textures itself (SKY_GLSL_EXACT_FILTER),
 * as the C does, and the texture unit filtering them (the library's
 * default), where the device filters R32G32B32A32_SFLOAT (lavapipe weighs
 * float formats in float: the same bounds hold).
 *
 * Bounds. The density is the same function bit for bit on the same float
 * inputs (test_glsl_cloud); what differs is the rest: the C marches in
 * double, the device in float, so a sample's position differs by a float's
 * ulps of its distance (1e-5 km at 100 km), the span's roots by their ulps
 * (the stable form), and exp, sqrt and the division are the device's
 * (Vulkan: 3 + 2|x| ulp, 3 ulp, 2.5 ulp). A density's gradient is at most
 * its extinction over a cumulus' soft edge (60 per km over some 40 m), so
 * a sample moves by under 1e-3 of its value; the radiance and the
 * transmittance are sums of such samples times exp of sums, and the
 * transmittance's stop (SKYCLOUD_MARCH_MIN_TRANSMITTANCE) may fall a step
 * apart, which moves what is left by under 1e-3 of the radiance. Hence
 * TOL_REL of each value plus TOL_ABS of the light's scale. The shadow's
 * optical depth is a bilinear lookup and an affine map in float: TOL_TAU
 * of it, and the depth's and the front's rounding (a few float ulps of
 * each, some 100 km) times the mean extinction. Measured worsts are
 * printed against these. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "skycloudmarch.h"
#include "test.h"
#include "test_glsl_vk.h"

#include "glsl_cloud_march.spv.h"
#include "glsl_cloud_march_hw.spv.h"

#define N_RECORDS 1024
#define RB 6360.0
#define RT 6460.0
#define EXTENT 60.0
#define COV_N 128
#define MAP_N 96
#define TR_W 32
#define TR_H 8
#define MS_N 16
#define TOL_REL 3e-3
#define TOL_ABS 1e-5		/* of the light's illuminance, in radiance */
#define TOL_TAU 1e-5

/* The scene as the shader reads it (std430): layers, SkycloudScene,
 * SkycloudLight, SkyState. */
struct gpu_scene {
	struct skycloud_layer layers[SKYCLOUD_MAX_LAYERS];
	float sc[6][4];
	float li[6][4];
	float sky[13][4];
};

struct record {
	float o[4], d[4], m[4], g[4];
};

struct scene_def {
	const char *name;
	int n;
	struct {
		int type;
		double cover, base_km, top_km;
	} l[SKYCLOUD_MAX_LAYERS];
	double sun_el_deg, observer_km;
	int table, light_steps, look_down;
};

static const struct scene_def scenes[] = {
	{ "broken stratocumulus, noon, tables", 1, { { SKYCLOUD_STRATOCUMULUS, 0.75, 1.0, 1.4 } }, 60.0, 0.1, 1, 0, 0 },
	{ "cumulus under cirrus, low sun, light march", 2,
	  { { SKYCLOUD_CUMULUS, 0.45, 1.0, 2.5 }, { SKYCLOUD_CIRRUS, 0.6, 8.0, 9.5 } }, 8.0, 0.3, 0, 4, 0 },
	{ "overcast stratus from above, tables", 1, { { SKYCLOUD_STRATUS, 1.0, 0.3, 0.7 } }, 30.0, 3.0, 1, 0, 1 },
	{ "four layers and a cumulonimbus, shadow map", 4,
	  { { SKYCLOUD_CUMULONIMBUS, 0.3, 0.8, 8.8 }, { SKYCLOUD_STRATOCUMULUS, 0.5, 1.2, 1.6 },
	    { SKYCLOUD_ALTOSTRATUS, 0.4, 3.5, 5.0 }, { SKYCLOUD_CIRRUS, 0.7, 9.0, 10.5 } },
	  25.0, 0.05, 0, 0, 0 },
};

static uint64_t rng_state = 0xc10d3a2cull;

static double rnd(void)
{
	return test_uniform(&rng_state);
}

static float tr_texels[4 * TR_W * TR_H], ms_texels[4 * MS_N * MS_N];
static float cov_texels[4 * COV_N * COV_N], map_texels[4 * MAP_N * MAP_N];
static struct skysample_table tr_t = { tr_texels, SKY_FORMAT_RGBA32F, TR_W, TR_H, 1, 0 };
static struct skysample_table ms_t = { ms_texels, SKY_FORMAT_RGBA32F, MS_N, MS_N, 1, 0 };
static struct skysample_table cov_t = { cov_texels, SKY_FORMAT_RGBA32F, COV_N, COV_N, 1, 0 };
static struct skysample_table map_t = { map_texels, SKY_FORMAT_RGBA32F, MAP_N, MAP_N, 1, 0 };

/* Smooth stand-ins for the sky's tables: reddening toward the horizon. */
static void make_sky_tables(void)
{
	for (int j = 0; j < TR_H; j++)
		for (int i = 0; i < TR_W; i++)
			for (int c = 0; c < 4; c++) {
				double u = (i + 0.5) / TR_W, v = (j + 0.5) / TR_H;
				tr_texels[4 * (j * TR_W + i) + c] =
					c == 3 ? 1.0f : (float)exp(-(0.1 + 0.9 * u) * (1.0 - 0.5 * v) * (1 << c) * 0.3);
			}
	for (int j = 0; j < MS_N; j++)
		for (int i = 0; i < MS_N; i++)
			for (int c = 0; c < 4; c++) {
				double u = (i + 0.5) / MS_N, v = (j + 0.5) / MS_N;
				ms_texels[4 * (j * MS_N + i) + c] =
					c == 3 ? 0.3f : (float)(0.004 * u * u * (1.0 - 0.5 * v) * (3 - c));
			}
}

struct world {
	struct skycloud_layer layers[SKYCLOUD_MAX_LAYERS];
	struct skycloud_scene sc;
	struct skycloud_light li;
	struct skycloud_sky sky;
	double observer_km;
};

/* The scene's layers, its coverage table and shadow map (the C twin of
 * the daemon's passes), as the C march takes them. */
static void make_world(const struct scene_def *s, uint32_t seed, struct world *w)
{
	const float off[2] = { 311.5f, 907.25f };
	/* The table made before the wind's last move (the slot's
	 * table_shift_km): both marches must read it shifted. */
	const double shift[2] = { 0.3125, -0.1875 };
	const float table_off[2] = { (float)(off[0] - shift[0]), (float)(off[1] - shift[1]) };
	for (int i = 0; i < s->n; i++)
		skycloud_layer_init(&w->layers[i], s->l[i].type, s->l[i].cover, s->l[i].base_km, s->l[i].top_km, seed,
				    (uint32_t)i);
	skycloud_scene_init(&w->sc, w->layers, s->n, off);
	w->sc.ambient_lx[0] = 3000.0;
	w->sc.ambient_lx[1] = 5000.0;
	w->sc.ambient_lx[2] = 8000.0;
	w->sc.diffusion = s->table;	/* both sources: a client's (from a slot) and the octaves' */
	for (int j = 0; j < COV_N; j++)
		for (int i = 0; i < COV_N; i++)
			for (int k = 0; k < 4; k++) {
				float x = (float)(-EXTENT + (i + 0.5) * 2.0 * EXTENT / COV_N);
				float y = (float)(-EXTENT + (j + 0.5) * 2.0 * EXTENT / COV_N);
				cov_texels[4 * (j * COV_N + i) + k] =
					k < s->n ? skycloud_coverage(&w->layers[k], x, y, table_off) : 0.0f;
			}
	memset(&w->li, 0, sizeof(w->li));
	double e = s->sun_el_deg * SKYMAP_PI / 180.0, a = 2.4;
	w->li.dir[0] = cos(e) * sin(a);
	w->li.dir[1] = cos(e) * cos(a);
	w->li.dir[2] = sin(e);
	w->li.illuminance_lx[0] = 120000.0;
	w->li.illuminance_lx[1] = 125000.0;
	w->li.illuminance_lx[2] = 118000.0;
	double top = 0.0;
	for (int i = 0; i < s->n; i++)
		top = s->l[i].top_km > top ? s->l[i].top_km : top;
	skycloud_shadow_frame_init(w->li.dir, EXTENT, -EXTENT * EXTENT / RB, top, &w->li.frame);
	w->li.frame.terrain_bias_km = 0.05;
	if (s->table) {
		w->sc.coverage = &cov_t;
		w->sc.extent_km = EXTENT;
		w->sc.table_shift_km[0] = shift[0];
		w->sc.table_shift_km[1] = shift[1];
	}
	for (int j = 0; j < MAP_N; j++)
		for (int i = 0; i < MAP_N; i++)
			skycloud_shadow_texel(&w->sc, RB, &w->li.frame, w->li.dir, (i + 0.5) / MAP_N, (j + 0.5) / MAP_N,
					      24, (i * 7 + j * 3) % 11 == 0 ? 20.0 : 1e30, &map_texels[4 * (j * MAP_N + i)]);
	w->li.shadow = &map_t;
	w->sky = (struct skycloud_sky){ &tr_t, &ms_t, RB, RT };
	w->observer_km = s->observer_km;
}

static void pack_scene(const struct world *w, struct gpu_scene *g)
{
	memset(g, 0, sizeof(*g));
	memcpy(g->layers, w->layers, sizeof(w->layers[0]) * (size_t)w->sc.n_layers);
	for (int i = 0; i < SKYCLOUD_MAX_LAYERS; i++) {
		g->sc[0][i] = (float)w->sc.phase_g[i];
		g->sc[1][i] = (float)w->sc.albedo[i];
	}
	g->sc[2][0] = (float)w->sc.octaves;
	g->sc[2][1] = (float)w->sc.octave_a;
	g->sc[2][2] = (float)w->sc.octave_b;
	g->sc[2][3] = (float)w->sc.octave_c;
	g->sc[3][0] = w->sc.offset_km[0];
	g->sc[3][1] = w->sc.offset_km[1];
	g->sc[3][2] = (float)w->sc.n_layers;
	g->sc[3][3] = w->sc.coverage ? (float)w->sc.extent_km : 0.0f;
	for (int c = 0; c < 3; c++) {
		g->sc[4][c] = (float)w->sc.ambient_lx[c];
		g->sc[4][3] = (float)w->sc.diffusion;
		g->sc[5][c % 2] = (float)w->sc.table_shift_km[c % 2];
		g->li[0][c] = (float)w->li.dir[c];
		g->li[1][c] = (float)w->li.illuminance_lx[c];
	}
	g->li[0][3] = w->li.shadow ? 1.0f : 0.0f;
	for (int c = 0; c < 4; c++) {
		g->li[2][c] = (float)w->li.frame.row_u[c];
		g->li[3][c] = (float)w->li.frame.row_v[c];
		g->li[4][c] = (float)w->li.frame.row_depth[c];
		g->sky[6][c] = 1.0f;	/* rgb_scale */
	}
	g->li[5][0] = (float)w->li.frame.terrain_bias_km;
	g->sky[4][0] = (float)RB;
	g->sky[4][1] = (float)RT;
	g->sky[4][2] = (float)w->observer_km;
}

static void make_records(const struct scene_def *s, struct record *rec, int n)
{
	static const int steps[] = { 16, 32, 64 };
	for (int i = 0; i < n; i++) {
		struct record *r = &rec[i];
		double az = rnd() * 2.0 * SKYMAP_PI, el = asin(rnd() * 1.1 - 0.1);
		if (s->look_down)
			el = -asin(rnd() * 0.9 + 0.1);
		r->o[0] = (float)(rnd() * 4.0 - 2.0);
		r->o[1] = (float)(rnd() * 4.0 - 2.0);
		r->o[2] = (float)s->observer_km;
		r->o[3] = (float)steps[i % 3];
		r->d[0] = (float)(cos(el) * sin(az));
		r->d[1] = (float)(cos(el) * cos(az));
		r->d[2] = (float)sin(el);
		r->d[3] = (i & 7) == 5 ? (float)(2.0 + 40.0 * rnd()) : 1e30f;
		r->m[0] = (float)s->light_steps;
		r->m[1] = (float)rnd();
		double gx = rnd() * 100.0 - 50.0, gy = rnd() * 100.0 - 50.0;
		r->g[0] = (float)gx;
		r->g[1] = (float)gy;
		r->g[2] = (float)((i & 3) ? -(gx * gx + gy * gy) / (2.0 * RB) : 1.0 + rnd() * 8.0);
	}
}

struct worst {
	double radiance, transmittance, depth, shadow, composite;
};

static void note(double *worst, double err, double bound, const char *what, int scene, int i)
{
	double q = err / bound;
	test_checks++;
	if (q > *worst)
		*worst = q;
	if (!(q <= 1.0)) {
		if (test_failures < 12)
			FAIL("scene %d record %d: %s: error %.3g over %.3g", scene, i, what, err, bound);
		else
			test_failures++;
	}
}

/* Checks the device's answers for one scene; ret_cloudy counts rays that
 * met a cloud. */
static void check(const struct world *w, const struct record *rec, const float *out, int scene, struct worst *wo,
		  int *ret_cloudy)
{
	double scale = TOL_ABS * w->li.illuminance_lx[1];
	for (int i = 0; i < N_RECORDS; i++) {
		const struct record *r = &rec[i];
		const float *g = out + 12 * i;
		double o[3] = { r->o[0], r->o[1], r->o[2] }, d[3] = { r->d[0], r->d[1], r->d[2] };
		double p[3] = { r->g[0], r->g[1], r->g[2] }, comp[3];
		struct skycloud_sample c;
		skycloud_march(&w->sc, &w->li, &w->sky, o, d, r->d[3], (int)r->o[3], (int)r->m[0], r->m[1], &c);
		for (int k = 0; k < 3; k++)
			note(&wo->radiance, fabs(g[k] - c.radiance[k]), TOL_REL * c.radiance[k] + scale, "radiance", scene,
			     i);
		note(&wo->transmittance, fabs(g[3] - c.transmittance), TOL_REL, "transmittance", scene, i);
		if (c.transmittance < 1.0)
			note(&wo->depth, fabs(g[4] - c.depth_km), TOL_REL * c.depth_km + 1e-3, "depth", scene, i);
		double tau = skycloud_shadow_depth(&map_t, &w->li.frame, p), tex[4];
		double dp = skycloud_affine(w->li.frame.row_depth, p);
		skysample_bilinear(&map_t, skycloud_affine(w->li.frame.row_u, p), skycloud_affine(w->li.frame.row_v, p),
				   0, 0, tex);
		/* The depth and the front in float: a few ulps of each, times
		 * the mean extinction. */
		double tol = TOL_TAU * (1.0 + tau) + 4.0 * FLT_EPSILON * tex[1] * (fabs(dp) + fabs(tex[0]));
		/* And the map's coordinates in float, a few ulps of 1: where
		 * the texels change steeply (a low sun across a cloud's edge)
		 * that moves the bilinear mix by the change over them. */
		for (int k = 0; k < 4; k++) {
			struct skycloud_shadow_frame f = w->li.frame;
			(k < 2 ? f.row_u : f.row_v)[3] += (k & 1 ? 4.0 : -4.0) * FLT_EPSILON;
			double t2 = skycloud_shadow_depth(&map_t, &f, p);
			if (t2 < SKYCLOUD_SHADOW_OPAQUE && tau < SKYCLOUD_SHADOW_OPAQUE)
				tol += fabs(t2 - tau);
		}
		if (tau >= SKYCLOUD_SHADOW_OPAQUE)
			CHECK(g[5] >= 1e29f && g[6] == 0.0f);
		else
			note(&wo->shadow, fabs(g[5] - tau), tol, "shadow depth", scene, i);
		note(&wo->shadow, fabs(g[6] - exp(-tau)), tol, "shadow", scene, i);
		skycloud_composite((const double[3]){ 1.0, 2.0, 3.0 }, &c, (const double[3]){ 0.25, 0.5, 0.75 }, 0.9,
				   comp);
		for (int k = 0; k < 3; k++)
			note(&wo->composite, fabs(g[8 + k] - comp[k]), TOL_REL * fabs(comp[k]) + 0.9 * scale + 1e-5,
			     "composite", scene, i);
		*ret_cloudy += c.transmittance < 0.99;
	}
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* One scene on the device: uploads, dispatch, the records' answers. */
static double run_scene(struct gvk *g, const struct world *w, const struct record *rec, int n, int hw,
			float *ret_out)
{
	int mb = g->n_buffers, mi = g->n_images;
	struct gvk_buffer *sb = gvk_buffer_new(g, sizeof(struct gpu_scene), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	struct gvk_buffer *in = gvk_buffer_new(g, sizeof(struct record) * n, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	struct gvk_buffer *out = gvk_buffer_new(g, 48 * (size_t)n, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	pack_scene(w, sb->map);
	memcpy(in->map, rec, sizeof(struct record) * n);
	const VkFormat f = VK_FORMAT_R32G32B32A32_SFLOAT;
	struct gvk_image *tr = gvk_image_new(g, f, TR_W, TR_H, 1, tr_texels, sizeof(tr_texels), 0, 0);
	struct gvk_image *ms = gvk_image_new(g, f, MS_N, MS_N, 1, ms_texels, sizeof(ms_texels), 0, 0);
	struct gvk_image *cov = gvk_image_new(g, f, COV_N, COV_N, 1, cov_texels, sizeof(cov_texels), 0, 0);
	struct gvk_image *map = gvk_image_new(g, f, MAP_N, MAP_N, 1, map_texels, sizeof(map_texels), 0, 0);
	struct gvk_binding b[7] = {
		{ VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, sb, NULL },
		{ VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, in, NULL },
		{ VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, out, NULL },
		{ VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, NULL, tr },
		{ VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, NULL, ms },
		{ VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, NULL, cov },
		{ VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, NULL, map },
	};
	double t0 = now_s();
	if (hw)
		gvk_dispatch(g, glsl_cloud_march_hw_spv, sizeof(glsl_cloud_march_hw_spv), b, 7, (uint32_t)(n + 63) / 64);
	else
		gvk_dispatch(g, glsl_cloud_march_spv, sizeof(glsl_cloud_march_spv), b, 7, (uint32_t)(n + 63) / 64);
	double t = now_s() - t0;
	if (ret_out)
		memcpy(ret_out, out->map, 48 * (size_t)n);
	gvk_release_to(g, mb, mi);
	return t;
}

/* --bench [SCENE]: the march's cost on the device against its step count,
 * a 256 x 128 grid of rays over the upper hemisphere through scene SCENE
 * (0 unless given; the
 * dispatch with 0 steps, timed beside each, is the fixed cost: the
 * pipeline's compilation and the uploads; the best of two of each). */
static void bench(struct gvk *g, int scene)
{
	enum { N = 256 * 128 };
	static struct record rec[N];
	struct world w;
	make_world(&scenes[scene], 7u, &w);
	make_records(&scenes[scene], rec, N);
	printf("%s\n", scenes[scene].name);
	for (int i = 0; i < N; i++) {
		double az = (i % 256 + 0.5) / 256 * 2.0 * SKYMAP_PI, el = asin((i / 256 + 0.5) / 128);
		rec[i].d[0] = (float)(cos(el) * sin(az));
		rec[i].d[1] = (float)(cos(el) * cos(az));
		rec[i].d[2] = (float)sin(el);
		rec[i].d[3] = 1e30f;
		rec[i].m[1] = 0.5f;
	}
	static const int steps[] = { 16, 32, 64, 128 };
	for (size_t k = 0; k < sizeof(steps) / sizeof(steps[0]); k++) {
		double base = 1e30, t = 1e30;
		for (int rep = 0; rep < 2; rep++)
			for (int z = 0; z < 2; z++) {
				for (int i = 0; i < N; i++)
					rec[i].o[3] = (float)(z ? steps[k] : 0);
				double s = run_scene(g, &w, rec, N, 0, NULL);
				if (z)
					t = s < t ? s : t;
				else
					base = s < base ? s : base;
			}
		printf("steps %3d: %7.1f ms for %d rays above the fixed %.1f ms: %.2f us a ray, %.0f ns a ray-step\n",
		       steps[k], 1e3 * (t - base), N, 1e3 * base, 1e6 * (t - base) / N,
		       1e9 * (t - base) / ((double)N * steps[k]));
	}
}

int main(int argc, char **argv)
{
	struct gvk g;
	if (gvk_open(&g) < 0) {
		printf("skipped: no Vulkan loader or device\n");
		return 77;
	}
	printf("device: %s\n", g.device_name);
	CHECK_EQ(sizeof(struct gpu_scene), 688);
	make_sky_tables();
	if (argc > 1 && strcmp(argv[1], "--bench") == 0) {
		int scene = argc > 2 ? atoi(argv[2]) : 0;
		bench(&g, scene >= 0 && scene < (int)(sizeof(scenes) / sizeof(scenes[0])) ? scene : 0);
		gvk_close(&g);
		return 0;
	}
	static struct record rec[N_RECORDS];
	static float out[12 * N_RECORDS];
	int filters = gvk_linear_ok(&g, VK_FORMAT_R32G32B32A32_SFLOAT) ? 2 : 1;
	if (filters == 1)
		printf("the device does not filter R32G32B32A32_SFLOAT: the shader's filter alone\n");
	for (int hw = 0; hw < filters; hw++) {
		struct worst wo = { 0 };
		printf("%s:\n", hw ? "filtered by the texture unit" : "filtered in the shader (SKY_GLSL_EXACT_FILTER)");
		for (size_t s = 0; s < sizeof(scenes) / sizeof(scenes[0]); s++) {
			struct world w;
			int cloudy = 0;
			make_world(&scenes[s], 1000u + (uint32_t)s, &w);
			rng_state = 0xc10d3a2cull + s;
			make_records(&scenes[s], rec, N_RECORDS);
			double t = run_scene(&g, &w, rec, N_RECORDS, hw, out);
			check(&w, rec, out, (int)s, &wo, &cloudy);
			printf("  %-44s %4d of %d rays through cloud, device %.2f s\n", scenes[s].name, cloudy,
			       N_RECORDS, t);
			CHECK(cloudy > N_RECORDS / 8);
		}
		printf("  worst error / bound: radiance %.3f, transmittance %.3f, depth %.3f, shadow %.3f, "
		       "composite %.3f\n", wo.radiance, wo.transmittance, wo.depth, wo.shadow, wo.composite);
	}
	gvk_close(&g);
	return test_report("test_glsl_cloud_march");
}
