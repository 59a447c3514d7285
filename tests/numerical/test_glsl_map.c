/* test_glsl_map.c - proto/glsl/skymap.glsl against proto/skymap.h: every
 * mapping run on the Vulkan device (lavapipe) at many points, including the
 * edges (horizon, zenith, nadir, the top of the shell, outside the range),
 * compared with the double-precision C functions (the panorama's across
 * north, outside an arc and beyond its rows among them), and the file's
 * SKYMAP_GLSL_VERSION with SKYMAP_VERSION. The two files are the one
 * definition of the mappings in two languages; this keeps them one.
 *
 * Tolerance: a texture coordinate may differ by TOL_TEXEL of a texel, 1/512:
 * half the 8-bit sub-texel precision with which texture units weigh
 * neighbours, so a float mapping that passes is indistinguishable from the
 * exact one through a sampler. Near the square-root packings (the sky-view
 * horizon, the multi-scattering table's earth shadow) a rounding of the
 * argument by a float ulp moves the root by sqrt(ulp), far more than
 * elsewhere: there the bound is that of the root of the argument's float
 * error (see kink_tol), which the daemon's shaders, also float, share. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "skymap.h"
#include "test.h"
#include "test_glsl_vk.h"

#include "glsl_map.spv.h"

#define N_RECORDS 20000
#define OUT_PER_RECORD 7
#define TOL_TEXEL (1.0 / 512.0)

struct record {
	float geo[4];		/* rb, rt, altitude_km, mu */
	float ang[4];		/* horizon_cos, view zenith, azimuth, depth_km */
	float tex[4];		/* u, v, unit x, aerial range_km */
	int32_t n[4];		/* width, height (slices), slice k, squared */
	float hor[4];		/* the horizon's cos, sin, zenith angle (double, rounded) */
	float dir[4];		/* a view direction, ENU */
	float pan[4];		/* a panorama: azimuth0_rad, azimuth_step_rad, row0, row_step */
	float pq[4];		/* its horizon_rad; a direction's azimuth and elevation (rad) */
	int32_t pn[4];		/* its width, height, full_circle */
};

static uint64_t rng_state = 0x5eed5eedull;

static double rnd(void)
{
	return test_uniform(&rng_state);
}

static float pick(const float *v, int n)
{
	return v[(int)(rnd() * n) % n];
}

/* Record i's panorama (an arc or the full circle, rows packed toward a
 * horizon at or below 0, whose top row may stop short of the zenith) and
 * a direction: anywhere, across north, outside the arc or at its ends, at
 * the horizon, or above the top row or below the bottom one. */
static void make_panorama(int i, struct record *r)
{
	static const float widths[] = { 3, 17, 48, 97 }, heights[] = { 4, 16, 24 };
	int w = (int)pick(widths, 4), h = (int)pick(heights, 3), full = rnd() < 0.5;
	double az0 = (4.0 * rnd() - 1.0) * SKYMAP_PI;
	double step = full ? 2.0 * SKYMAP_PI / (w - 1) : (0.1 + 5.9 * rnd()) / (w - 1);
	double horizon = -0.1 * rnd(), row0 = -sqrt(0.05 + 0.3 * rnd());
	double top = sqrt(0.5 * SKYMAP_PI - horizon) * (0.6 + 0.5 * rnd());
	double row_step = (top - row0) / (h - 1), span = step * (w - 1);
	double az = (6.0 * rnd() - 2.0) * SKYMAP_PI, el = asin(2.0 * rnd() - 1.0);
	switch (i % 5) {
	case 1:		/* across north, one turn either way */
		az = 0.2 * (rnd() - 0.5) + 2.0 * SKYMAP_PI * (int)(3.0 * rnd() - 1.0);
		break;
	case 2:		/* outside the arc, or near an end of it */
		az = az0 + (rnd() < 0.5 ? span + rnd() * (2.0 * SKYMAP_PI - span)
					 : (rnd() < 0.5 ? span : 0.0) + 0.01 * (rnd() - 0.5));
		break;
	case 3:		/* at the horizon, where the rows' root has its kink */
		el = horizon + 1e-3 * (rnd() - 0.5);
		break;
	case 4:		/* above the top row or below the bottom one */
		el = rnd() < 0.5 ? fmin(horizon + top * top + rnd(), 0.5 * SKYMAP_PI)
				 : fmax(horizon - row0 * row0 - rnd(), -0.5 * SKYMAP_PI);
		break;
	}
	r->pan[0] = (float)az0;
	r->pan[1] = (float)step;
	r->pan[2] = (float)row0;
	r->pan[3] = (float)row_step;
	r->pq[0] = (float)horizon;
	r->pq[1] = (float)az;
	r->pq[2] = (float)el;
	r->pn[0] = w;
	r->pn[1] = h;
	r->pn[2] = full;
}

/* Record i: a planet, an altitude and a cosine, one in four at an edge. */
static void make_record(int i, struct record *r)
{
	static const float planets[][2] = { { 6360.0f, 6420.0f }, { 3389.5f, 3489.5f }, { 6360.0f, 6460.0f } };
	static const float widths[] = { 8, 32, 64, 256 }, heights[] = { 4, 16, 32, 64, 128 };
	const float *p = planets[i % 3];
	double rb = p[0], rt = p[1], shell = rt - rb;
	int edge = (i & 3) == 0;
	double alt = rnd() * shell;
	if (edge) {
		const double alts[] = { 0.0, 1e-3, shell, shell - 1e-3, -0.01, shell + 1.0, 0.5 };
		alt = alts[(int)(rnd() * 7) % 7];
	}
	double hc = skymap_horizon_cos(rb, (float)alt);
	double mu = 2.0 * rnd() - 1.0;
	if (edge || (i & 7) == 1) {
		const double mus[] = { -1.0, 1.0, 0.0, hc, hc + 1e-4, hc - 1e-4, hc + 1e-2, 0.999999 };
		mu = mus[(int)(rnd() * 8) % 8];
	}
	r->geo[0] = (float)rb;
	r->geo[1] = (float)rt;
	r->geo[2] = (float)alt;
	r->geo[3] = (float)mu;
	r->n[0] = (int)pick(widths, 4);
	r->n[1] = (int)pick(heights, 5);
	r->n[2] = (int)(rnd() * r->n[1]);
	r->n[3] = (int)(rnd() * 2);
	/* The horizon of the record's (float) altitude, as a client's double
	 * state would give it. */
	r->ang[0] = (float)skymap_horizon_cos(rb, r->geo[2]);
	double th = acos(r->ang[0]);
	double z = rnd() * SKYMAP_PI;
	if (edge) {
		const double zs[] = { 0.0, SKYMAP_PI, th, th + 1e-3, th - 1e-3, 0.5 * SKYMAP_PI };
		z = zs[(int)(rnd() * 6) % 6];
	}
	r->ang[1] = (float)z;
	double hr = rb + fmax(r->geo[2], 0.0);
	r->hor[0] = r->ang[0];
	r->hor[1] = (float)(rb / hr);
	r->hor[2] = (float)th;
	/* A direction at the zenith angle z (the horizon itself one time in
	 * four), any azimuth. */
	double az = rnd() * 2.0 * SKYMAP_PI;
	r->dir[0] = (float)(sin(z) * sin(az));
	r->dir[1] = (float)(sin(z) * cos(az));
	r->dir[2] = (float)cos(z);
	r->ang[2] = (float)((rnd() * 4.0 - 2.0) * SKYMAP_PI);	/* two turns each way: wraps */
	r->tex[3] = (float)(1.0 + rnd() * 99.0);
	r->ang[3] = (float)(rnd() * 1.2 * r->tex[3]);
	/* Texture coordinates between the first and last texel centres. */
	r->tex[0] = (float)skymap_unit_to_tex(rnd(), (unsigned)r->n[0]);
	r->tex[1] = (float)skymap_unit_to_tex(rnd(), (unsigned)r->n[1]);
	r->tex[2] = (float)rnd();
	make_panorama(i, r);
}

struct worst {
	const char *what;
	double err;	/* worst error over its tolerance */
	int record;
	int failed;
};

static void note(struct worst *w, double err, double tol, int i)
{
	double q = err / tol;
	test_checks++;
	if (!(q <= w->err))
		w->err = q, w->record = i;
	if (!(q <= 1.0) && w->failed++ < 3)
		FAIL("%s: record %d: error %.3g over tolerance %.3g", w->what, i, err, tol);
	else if (!(q <= 1.0))
		test_failures++;
}

/* The tolerance of a unit coordinate on an axis of n texels that went
 * through sqrt(s) at s: TOL_TEXEL, or what an error ds of s does to the
 * root near s = 0. */
#define DS_FLOAT (4.0 * 1.2e-7)	/* a few ulps of s's unit-size terms */
/* The sky-view's angle forms take the horizon's angle from the GPU's atan
 * (skymap_horizon_rad), good to about 1e-6 rad on lavapipe: s moves by
 * that over pi - theta_h. */
#define DS_GPU_ATAN 4e-6

static double kink_tol_ds(double s, unsigned n, double ds)
{
	double root = sqrt(fabs(s) + ds) - sqrt(fabs(s));
	return TOL_TEXEL / n + 0.5 * root;
}

static double kink_tol(double s, unsigned n)
{
	return kink_tol_ds(s, n, DS_FLOAT);
}

static double wrap_diff(double a, double b)
{
	double d = fabs(a - b);
	d -= floor(d);
	return d > 0.5 ? 1.0 - d : d;
}

/* skymap_panorama_uv against its definition (PROTOCOL.md, "Panoramas"),
 * written out here, where a direction lies inside the panorama: column
 * (azimuth - azimuth0 mod 2 pi) / step, row (x - row0) / row_step with
 * x = sign(e) sqrt(|e|); outside an arc the nearer end, beyond the rows
 * the first or last. A mapping that moves in skymap.h fails here even if
 * skymap.glsl moves with it. */
static void check_panorama_definition(const struct record *r, double u, double v, int i,
				      struct worst *w)
{
	double az0 = r->pan[0], step = r->pan[1], row0 = r->pan[2], row_step = r->pan[3];
	unsigned W = (unsigned)r->pn[0], H = (unsigned)r->pn[1];
	double du = fmod(r->pq[1] - az0, 2.0 * SKYMAP_PI), span = step * (W - 1);
	if (du < 0.0)
		du += 2.0 * SKYMAP_PI;
	double f = du / step;
	if (!r->pn[2] && du > span) {
		double past = du - span, before = 2.0 * SKYMAP_PI - du;
		if (fabs(past - before) < 1e-6)
			return;
		f = past < before ? W - 1.0 : 0.0;
	}
	double e = (double)r->pq[2] - r->pq[0], x = e < 0.0 ? -sqrt(-e) : sqrt(e);
	double g = fmin(fmax((x - row0) / row_step, 0.0), H - 1.0);
	f = fmin(fmax(f, 0.0), W - 1.0);
	note(w, fabs(u - (f + 0.5) / W), 1e-12, i);
	note(w, fabs(v - (g + 0.5) / H), 1e-12, i);
}

/* The GLSL panorama mapping against skymap.h: TOL_TEXEL, plus the root's
 * float error at the horizon (as kink_tol); a full circle's first and last
 * columns are the same azimuth, and an arc's two ends are a float rounding
 * apart half way round outside it, so those read as one. */
static void check_panorama(const struct record *r, const float *o, int i, struct worst *w)
{
	unsigned W = (unsigned)r->pn[0], H = (unsigned)r->pn[1];
	double u, v;
	skymap_panorama_uv(r->pan[0], r->pan[1], r->pan[2], r->pan[3], r->pq[0], W, H, r->pn[2] != 0,
			   r->pq[1], r->pq[2], &u, &v);
	check_panorama_definition(r, u, v, i, &w[11]);
	double eu = fabs(o[0] - u);
	if (r->pn[2])
		eu = fmin(eu, fabs(eu - (W - 1.0) / W));
	double du = fmod((double)r->pq[1] - r->pan[0], 2.0 * SKYMAP_PI), span = (double)r->pan[1] * (W - 1);
	if (du < 0.0)
		du += 2.0 * SKYMAP_PI;
	if (!r->pn[2] && du > span && fabs((du - span) - (2.0 * SKYMAP_PI - du)) < 1e-4)
		eu = fmin(eu, fabs(eu - (W - 1.0) / W));
	note(&w[10], eu, TOL_TEXEL / W, i);
	double e = fabs((double)r->pq[2] - r->pq[0]);
	note(&w[10], fabs(o[1] - v),
	     TOL_TEXEL / H + (sqrt(e + DS_FLOAT) - sqrt(e)) / ((double)r->pan[3] * H), i);
}

static void check(const struct record *rec, const float *out, int n, struct worst *w)
{
	for (int i = 0; i < n; i++) {
		const struct record *r = &rec[i];
		const float *o = out + 4 * OUT_PER_RECORD * i;
		double rb = r->geo[0], rt = r->geo[1], alt = r->geo[2], mu = r->geo[3];
		unsigned W = (unsigned)r->n[0], H = (unsigned)r->n[1];
		double u, v, a, m;

		skymap_transmittance_uv(rb, rt, alt, mu, W, H, &u, &v);
		note(&w[0], fabs(o[0] - u), TOL_TEXEL / W, i);
		note(&w[0], fabs(o[1] - v), TOL_TEXEL / H, i);

		/* The multi-scattering u has its root at mu_s = the horizon. */
		double mh = skymap_horizon_cos(rb, skymap_clamp(alt, 0.0, rt - rb));
		double s = (skymap_clamp(mu, -1.0, 1.0) - mh) / (mu < mh ? 1.0 + mh : 1.0 - mh);
		skymap_multiscatter_uv(rb, rt, alt, mu, W, H, &u, &v);
		note(&w[1], fabs(o[2] - u), kink_tol(s, W), i);
		note(&w[1], fabs(o[3] - v), TOL_TEXEL / H, i);

		/* Inverses: back through the C forward mapping to the texel they
		 * came from. */
		skymap_transmittance_uv(rb, rt, o[4], o[5], W, H, &u, &v);
		note(&w[2], fabs(u - r->tex[0]), TOL_TEXEL / W, i);
		note(&w[2], fabs(v - r->tex[1]), TOL_TEXEL / H, i);
		skymap_multiscatter_inverse(rb, rt, r->tex[0], r->tex[1], W, H, &a, &m);
		note(&w[3], fabs(o[6] - a), 1e-5 * (rt - rb), i);
		note(&w[3], fabs(o[7] - m), 4e-7 + 1e-6 * fabs(m), i);

		double hc = r->ang[0], th = acos(hc), z = r->ang[1];
		double sk = z < th ? 1.0 - z / th : (z - th) / (SKYMAP_PI - th);
		skymap_skyview_uv(hc, z, r->ang[2], H, &u, &v);
		note(&w[4], wrap_diff(o[8], u), TOL_TEXEL / W, i);
		note(&w[4], fabs(o[9] - v), kink_tol_ds(sk, H, DS_GPU_ATAN), i);
		/* The direction form, against the angles of the float direction. */
		double dx = r->dir[0], dy = r->dir[1], dz = r->dir[2];
		double dn = sqrt(dx * dx + dy * dy + dz * dz);
		double zd = atan2(sqrt(dx * dx + dy * dy), dz), azd = atan2(dx, dy);
		skymap_skyview_uv(hc, zd, azd, H, &u, &v);
		sk = zd < th ? 1.0 - zd / th : (zd - th) / (SKYMAP_PI - th);
		/* At the zenith and the nadir every azimuth is the same texel. */
		if (sqrt(dx * dx + dy * dy) > 1e-5)
			note(&w[9], wrap_diff(o[20], u), TOL_TEXEL / W, i);
		note(&w[9], fabs(o[21] - v), kink_tol(sk, H) + fabs(dn - 1.0), i);
		/* The file's version is skymap.h's. */
		if (i == 0)
			CHECK(o[22] == SKYMAP_VERSION);
		double zen, az;
		skymap_skyview_inverse(hc, r->tex[0], r->tex[1], H, &zen, &az);
		note(&w[5], fabs(o[10] - zen), 2e-6 * SKYMAP_PI, i);
		note(&w[5], fabs(o[11] - az), 1e-6 * 2.0 * SKYMAP_PI, i);

		int sq = r->n[3] != 0;
		double range = r->tex[3];
		double dk = skymap_aerial_depth_km((unsigned)r->n[2], H, range, sq);
		note(&w[6], fabs(o[12] - dk), 4e-7 * dk, i);
		double wk = skymap_aerial_slice(r->ang[3], H, range, sq);
		note(&w[6], fabs(o[13] - wk), TOL_TEXEL, i);

		note(&w[7], fabs(o[14] - skymap_horizon_cos(rb, alt)), 1e-6, i);
		double d = skymap_distance_to_top(rb, rt, skymap_clamp(alt, 0.0, rt - rb), mu);
		/* d's own float error grows with r mu: relative to the ray's
		 * distance to the top and to the shell's scale. */
		if (alt >= 0.0 && alt <= rt - rb)
			note(&w[7], fabs(o[15] - d), 1e-6 * (d + rb), i);
		note(&w[8], fabs(o[16] - skymap_rho2(rb, alt)), 4e-7 * fabs(skymap_rho2(rb, alt)) + 1e-12, i);
		note(&w[8], fabs(o[17] - skymap_unit_to_tex(r->tex[2], W)), 1e-7, i);
		note(&w[8], fabs(o[18] - skymap_tex_to_unit(r->tex[0], W)), 2e-7, i);
		check_panorama(r, o + 24, i, w);
	}
}

int main(void)
{
	struct gvk g;
	int r = gvk_open(&g);
	if (r < 0) {
		printf("skipped: no Vulkan loader or device\n");
		return 77;
	}
	printf("device: %s\n", g.device_name);
	struct gvk_buffer *in = gvk_buffer_new(&g, sizeof(struct record) * N_RECORDS,
					       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	struct gvk_buffer *out = gvk_buffer_new(&g, 16 * OUT_PER_RECORD * N_RECORDS,
						VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	struct record *rec = in->map;
	for (int i = 0; i < N_RECORDS; i++)
		make_record(i, &rec[i]);
	struct gvk_binding b[2] = { { VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, in, NULL },
				    { VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, out, NULL } };
	gvk_dispatch(&g, glsl_map_spv, sizeof(glsl_map_spv), b, 2, (N_RECORDS + 63) / 64);

	struct worst w[] = { { "transmittance_uv", 0, -1, 0 }, { "multiscatter_uv", 0, -1, 0 },
			     { "transmittance_inverse", 0, -1, 0 }, { "multiscatter_inverse", 0, -1, 0 },
			     { "skyview_uv", 0, -1, 0 }, { "skyview_inverse", 0, -1, 0 },
			     { "aerial_depth_km, aerial_slice", 0, -1, 0 },
			     { "horizon_cos, distance_to_top", 0, -1, 0 },
			     { "rho2, unit_to_tex, tex_to_unit", 0, -1, 0 },
			     { "skyview_uv_dir", 0, -1, 0 }, { "panorama_uv", 0, -1, 0 },
			     { "panorama_uv (skymap.h) by definition", 0, -1, 0 } };
	check(rec, out->map, N_RECORDS, w);
	for (size_t i = 0; i < sizeof(w) / sizeof(w[0]); i++)
		printf("%-32s worst error / tolerance %.3f (record %d)\n", w[i].what, w[i].err, w[i].record);
	gvk_close(&g);
	return test_report("test_glsl_map");
}
