/* test_glsl_cloud.c - proto/glsl/skycloud.glsl against proto/skycloud.h:
 * every function run on the Vulkan device (lavapipe here) for many
 * records, edges included (the wrap of the period, offsets just under it,
 * altitudes at a layer's base and top, cover 0 and 1, seeds 0 and
 * 2^32 - 1), against the C float build on the same float inputs. The
 * layers travel as the C array of struct skycloud_layer, so the GLSL
 * struct's layout is checked with them.
 *
 * Bounds: the hash, the noises, the coverage fBm, margin and coverage, the
 * detail, the profile and the density (one layer and all) bit for bit:
 * they are +, -, *, floor and integer operations, precise in the GLSL.
 * The sky occlusion within TOL_OCCLUSION (the device's exp: 3 + 2|x| ulp,
 * Vulkan's bound) and the optical depth within TOL_TAU_REL of itself plus
 * TOL_TAU_ABS (the device's sqrt and dot in the altitude and the ray's
 * span move the sample points by ulps; the density is continuous). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "skycloud.h"
#include "test.h"
#include "test_glsl_vk.h"

#include "glsl_cloud.spv.h"

#define N_GROUPS 64
#define N_RECORDS 16384
#define OUT_PER_RECORD 3
#define TOL_OCCLUSION 1e-5
#define TOL_TAU_REL 1e-3
#define TOL_TAU_ABS 1e-3

struct record {
	float p[4];	/* x, y, h, layers of the group */
	float q[4];	/* offset east, north, planet radius, max_km */
	float o[4];	/* ray origin, steps */
	float d[4];	/* ray direction */
	uint32_t h[4];	/* hash input i, j, k; the group */
};

static uint64_t rng_state = 0xc10dull;

static double rnd(void)
{
	return test_uniform(&rng_state);
}

/* Group g: four layers of any type and cover, bases and tops across the
 * range, every seed but the ends one time in eight. */
static void make_group(int g, struct skycloud_layer *L)
{
	static const uint32_t seeds[] = { 0u, 0xffffffffu, 1u, 2024u };
	for (int k = 0; k < SKYCLOUD_MAX_LAYERS; k++) {
		int type = (int)(rnd() * SKYCLOUD_N_TYPES) % SKYCLOUD_N_TYPES;
		double cover = (g % 5 == 0) ? (k & 1) : (int)(rnd() * 9) / 8.0;
		double base = (g % 7 == 0) ? 0.0 : rnd() * 12.0;
		double top = base + skycloud_types[type].thickness_m * 1e-3 * (0.5 + rnd());
		uint32_t seed = g % 8 == 0 ? seeds[k] : (uint32_t)(rnd() * 4294967295.0);
		skycloud_layer_init(&L[k], type, cover, base, fmin(top, 20.0), seed, (uint32_t)k);
	}
}

/* Record i of group g: a point near one of the group's layers (at its base
 * or top one time in eight), an offset (0 or just under the period one
 * time in eight), positions across the wrap, and a ray from near the
 * ground or from above the layers. */
static void make_record(int i, const struct skycloud_layer *group, struct record *r)
{
	const struct skycloud_layer *L = &group[i & 3];
	int edge = (i & 7) == 0;
	double x = rnd() * 1200.0 - 600.0, y = rnd() * 1200.0 - 600.0;
	if (edge) {
		const double xs[] = { 0.0, 512.0, -512.0, 1024.0, -0.001, 1023.999 };
		x = xs[(int)(rnd() * 6) % 6];
	}
	double h = L->base_km + (L->top_km - L->base_km) * (rnd() * 1.2 - 0.1);
	if (edge)
		h = rnd() < 0.5 ? L->base_km : L->top_km;
	double ox = rnd() * SKYCLOUD_PERIOD_KM, oy = rnd() * SKYCLOUD_PERIOD_KM;
	if ((i & 7) == 1)
		ox = oy = (i & 8) ? 0.0 : 1023.9999;
	r->p[0] = (float)x;
	r->p[1] = (float)y;
	r->p[2] = (float)h;
	r->p[3] = (float)(1 + (i >> 2) % 4);
	r->q[0] = (float)ox;
	r->q[1] = (float)oy;
	r->q[2] = 6360.0f;
	r->q[3] = 300.0f;
	double az = rnd() * 2.0 * M_PI, el = asin(rnd() * 2.0 - 1.0);
	if ((i & 3) == 0)
		el = fabs(el);
	r->o[0] = (float)(rnd() * 20.0 - 10.0);
	r->o[1] = (float)(rnd() * 20.0 - 10.0);
	r->o[2] = (float)((i & 16) ? 0.2 : 14.0 * rnd());
	r->o[3] = (float)(8 + (i % 5) * 16);
	r->d[0] = (float)(cos(el) * sin(az));
	r->d[1] = (float)(cos(el) * cos(az));
	r->d[2] = (float)sin(el);
	r->d[3] = 0.0f;
	r->h[0] = (uint32_t)(rnd() * 4294967295.0);
	r->h[1] = i & 1 ? 0u : (uint32_t)(rnd() * 4294967295.0);
	r->h[2] = (uint32_t)i;
}

struct tally {
	const char *what;
	long differ;		/* bit for bit: records that differ */
	double worst;		/* bounded: the worst error over its bound */
};

static void same_bits(struct tally *t, float gpu, float cpu, int i)
{
	test_checks++;
	if (memcmp(&gpu, &cpu, sizeof(float)) != 0) {
		uint32_t bits;
		memcpy(&bits, &gpu, sizeof(bits));
		if (t->differ++ < 3)
			FAIL("%s: record %d: device %.9g (0x%08x), C %.9g", t->what, i, gpu, bits, cpu);
		else
			test_failures++;
	}
}

static void within(struct tally *t, double err, double tol, int i)
{
	double q = err / tol;
	test_checks++;
	if (!(q <= t->worst))
		t->worst = q;
	if (!(q <= 1.0)) {
		if (t->differ++ < 3)
			FAIL("%s: record %d: error %.3g over %.3g", t->what, i, err, tol);
		else
			test_failures++;
	}
}

/* ret_cloudy, ret_rays: records inside a cloud, rays that cross one. */
static void check(const struct skycloud_layer *layers, const struct record *rec, const float *out,
		  const uint32_t *outu, struct tally *t, int *ret_cloudy, int *ret_rays)
{
	for (int i = 0; i < N_RECORDS; i++) {
		const struct record *r = &rec[i];
		const struct skycloud_layer *group = &layers[4 * r->h[3]];
		const struct skycloud_layer *L = &group[i & 3];
		const float *o = out + 4 * OUT_PER_RECORD * i;
		int n = (int)r->p[3];
		float px = skycloud_wrap(r->p[0] - r->q[0]), py = skycloud_wrap(r->p[1] - r->q[1]);
		uint32_t v[3] = { r->h[0], r->h[1], r->h[2] }, key[3] = { r->h[2], r->h[1], r->h[0] };
		skycloud_pcg3d(v);
		const uint32_t hkey[3] = { r->h[3], 7u, 9u };
		test_checks++;
		if (memcmp(v, &outu[4 * i], sizeof(v)) != 0 ||
		    outu[4 * i + 3] != skycloud_hash3(r->h[0], r->h[1], r->h[2], hkey)) {
			t[0].differ++;
			FAIL("hash: record %d", i);
		}
		same_bits(&t[1], o[8], skycloud_noise2(px, py, L->coverage_scale * 4.0f,
							(const uint32_t *)r->h), i);
		same_bits(&t[1], o[9], skycloud_noise3(px, py, skycloud_wrap(r->p[2]),
							L->detail_scale * 2.0f, key), i);
		same_bits(&t[2], o[0], skycloud_coverage_fbm(L, px, py), i);
		same_bits(&t[2], o[1], skycloud_coverage_margin(L, r->p[0], r->p[1], r->q), i);
		same_bits(&t[2], o[2], skycloud_coverage(L, r->p[0], r->p[1], r->q), i);
		same_bits(&t[3], o[3], skycloud_detail(L, px, py, skycloud_wrap(r->p[2])), i);
		same_bits(&t[3], o[10], skycloud_profile(L, r->p[2] - floorf(r->p[2])), i);
		same_bits(&t[4], o[4], skycloud_density(L, r->p[0], r->p[1], r->p[2], r->q), i);
		same_bits(&t[4], o[5], skycloud_density_all(group, n, r->p[0], r->p[1], r->p[2], r->q), i);
		within(&t[5], fabs(o[6] - skycloud_sky_occlusion(group, n, r->p[2])), TOL_OCCLUSION, i);
		float tau = skycloud_optical_depth(group, n, r->q, r->q[2], r->o, r->d, r->q[3], (int)r->o[3]);
		within(&t[6], fabs(o[7] - tau), TOL_TAU_ABS + TOL_TAU_REL * tau, i);
		*ret_cloudy += o[4] > 0.0f;
		*ret_rays += tau > 0.0f;
		if (i == 0)
			CHECK_EQ(o[11], SKYCLOUD_VERSION);
	}
}

int main(void)
{
	struct gvk g;
	if (gvk_open(&g) < 0) {
		printf("skipped: no Vulkan loader or device\n");
		return 77;
	}
	printf("device: %s\n", g.device_name);
	CHECK_EQ(sizeof(struct skycloud_layer), 72);	/* 18 4-byte scalars: std430's stride */
	struct gvk_buffer *lb = gvk_buffer_new(&g, sizeof(struct skycloud_layer) * 4 * N_GROUPS,
					       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	struct gvk_buffer *in = gvk_buffer_new(&g, sizeof(struct record) * N_RECORDS,
					       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	struct gvk_buffer *out = gvk_buffer_new(&g, 16 * OUT_PER_RECORD * N_RECORDS,
						VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	struct gvk_buffer *outu = gvk_buffer_new(&g, 16 * N_RECORDS, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	struct skycloud_layer *layers = lb->map;
	struct record *rec = in->map;
	for (int k = 0; k < N_GROUPS; k++)
		make_group(k, &layers[4 * k]);
	for (int i = 0; i < N_RECORDS; i++) {
		int k = i % N_GROUPS;
		make_record(i, &layers[4 * k], &rec[i]);
		rec[i].h[3] = (uint32_t)k;
	}
	struct gvk_binding b[4] = { { VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, lb, NULL },
				    { VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, in, NULL },
				    { VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, out, NULL },
				    { VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, outu, NULL } };
	gvk_dispatch(&g, glsl_cloud_spv, sizeof(glsl_cloud_spv), b, 4, (N_RECORDS + 63) / 64);

	struct tally t[] = { { "pcg3d, hash3", 0, 0 }, { "noise2, noise3", 0, 0 },
			     { "coverage fbm, margin, coverage", 0, 0 }, { "detail, profile", 0, 0 },
			     { "density, density_all", 0, 0 }, { "sky_occlusion", 0, 0 },
			     { "optical_depth", 0, 0 } };
	int cloudy = 0, rays = 0;
	check(layers, rec, out->map, outu->map, t, &cloudy, &rays);
	printf("%d records of %d inside a cloud, %d rays through one\n", cloudy, N_RECORDS, rays);
	CHECK(cloudy > N_RECORDS / 10 && rays > N_RECORDS / 4);
	for (int k = 0; k < 5; k++)
		printf("%-32s %s (%ld records differ)\n", t[k].what, t[k].differ ? "DIFFERS" : "bit for bit",
		       t[k].differ);
	for (int k = 5; k < 7; k++)
		printf("%-32s worst error / bound %.3f\n", t[k].what, t[k].worst);
	gvk_close(&g);
	return test_report("test_glsl_cloud");
}
