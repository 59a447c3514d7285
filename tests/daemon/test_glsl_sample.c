/* test_glsl_sample.c - the GLSL library (proto/glsl/sky.glsl) on lavapipe
 * against libsky's CPU sampling of the same generation of a real skyd.
 *
 * A client's path end to end: libsky subscribes, sky_snapshot() copies a
 * slot, sky_gpu_tables() and sky_gpu_state() describe it, the tables go to
 * Vulkan images as they are, and a compute shader that includes sky.glsl
 * evaluates the sky for 4096 directions, the disks, the transmittance
 * toward each direction and at an (altitude, mu), the multi-scattering
 * table, aerial perspective at screen positions and distances, and the
 * sun's and moon's illuminance. libsky (sky_sample_*, skysample.h) gives
 * the reference from the same snapshot. Three generations: float32 tables,
 * float16 tables (storage=f16: every table changed), then another sun
 * (sky-view and aerial changed, transmittance and multi-scattering not),
 * which also checks sky_gpu_tables()'s changed_generation. Then views:
 * one of form volume, then views of form panorama on the same eye point,
 * first one (an arc of azimuths), then four all round, one of them with
 * the zenith in its frustum (the full circle):
 * sky_gpu_view_table() and sky_gpu_state() must describe the panorama
 * (RGBA32F, its sizes, form 1 or 2), and sky.glsl's sky_aerial_dir() on
 * the uploaded texture must give libsky's sky_sample_view_aerial_dir(),
 * for the state's camera, the volume view and the panorama views.
 *
 * Tolerance, per lookup and channel, from the texels the lookup blends
 * (their spread S: the largest minus the smallest value over the cell's
 * texels and their neighbours, as the GPU's cell may be the next one, in
 * both slices a 3-D lookup blends, as the slice weight is rounded too):
 *   texture units: 3 S / 256 (2-D: 2 S / 256), because they weigh the
 *     texels with 8 bits of sub-texel position (an error up to 1/512 of a
 *     step per axis) and the float mapping may put the position up to
 *     1/512 texel off (test_glsl_map);
 *   SKY_GLSL_EXACT_FILTER: S / 256 (the mapping's part alone);
 * plus 4e-6 of the value, float32 arithmetic on the GPU against double
 * (a few ulps through the scale, the mix and the mapping). float16 tables
 * read the same halves on both sides, scaled exactly by the same power of
 * two, but the texture units may return the filtered value as a binary16
 * (an NVIDIA H100 does): one ulp of the value, 2^-10 of it, more. The disks: the transmittance toward the light as
 * above, times the disk's radiance, plus 1e-4 of it for the limb law in
 * float (a square root near the limb).
 *
 * sky_aerial_dir on a panorama: the lookup filters the logarithm, so the
 * bound is on log-RGB: the spread S of the log over the texels around the
 * lookup times (3 / 256 for the texture units, 1 / 256 exact, as above)
 * plus the texel distance that the GPU's float direction may move the
 * lookup (atan and asin of a direction rounded to float, found by moving
 * the azimuth and elevation by their float error and mapping again: large
 * only near the zenith, at the horizon's square-root kink and where an arc
 * is a rounding away from taking its other end), plus 2e-6 for the log
 * and exp in float; then the radiance's relative error is exp(that) - 1.
 * A (linear) takes the same factor on its own spread. A volume through
 * sky_aerial_dir is sky_aerial at the direction's screen position: the
 * aerial bound above. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "daemon_harness.h"
#include "sky.h"
#include "sky_set.h"
#include "skysample.h"
#include "test.h"
#include "test_glsl_vk.h"

#include "glsl_sample_exact.spv.h"
#include "glsl_sample_hw.spv.h"

#define N_QUERIES 4096
#define RESULTS_PER_QUERY 9
#define REL_TOL 4e-6

static const char *const args[] = {
	"transmittance_width=64", "transmittance_height=32", "transmittance_steps=16",
	"multiscatter_width=16", "multiscatter_height=16", "multiscatter_steps=8",
	"multiscatter_dirs=2", "skyview_width=64", "skyview_height=32", "skyview_steps=8",
	"aerial_width=16", "aerial_height=16", "aerial_depth=8", "aerial_range_km=40",
	"sun_elevation_deg=12", "sun_azimuth_deg=120", "moon_elevation_deg=35",
	"moon_azimuth_deg=250", "moon_illuminance_lx=0.3", "altitude_km=0.5", NULL
};

struct query {
	float dir[4];		/* view direction, w distance_km */
	float p[4];		/* screen u, v, altitude_km, mu */
};

static uint64_t rng_state = 0x51d0u;

static double rnd(void)
{
	return test_uniform(&rng_state);
}

/* A unit vector at angle a from the unit vector c, in a random plane. */
static void near_dir(const double c[3], double a, double ret[3])
{
	double t[3] = { -c[1], c[0], 0.0 };
	double n = sqrt(t[0] * t[0] + t[1] * t[1]);
	if (n < 1e-9)
		t[0] = 1.0, t[1] = 0.0, n = 1.0;
	for (int k = 0; k < 3; k++)
		t[k] /= n;
	double b[3] = { c[1] * t[2] - c[2] * t[1], c[2] * t[0] - c[0] * t[2], c[0] * t[1] - c[1] * t[0] };
	double ph = 2.0 * SKYMAP_PI * rnd();
	for (int k = 0; k < 3; k++)
		ret[k] = cos(a) * c[k] + sin(a) * (cos(ph) * t[k] + sin(ph) * b[k]);
}

/* The camera of an aerial volume: the state's, or a view's. */
struct camera {
	double fwd[3], right[3], up[3], tan_half, aspect;
};

static int camera_of(const struct sky_view *v, const char *name, struct camera *ret)
{
	const struct sky_shm_state *st = &v->slot->state;
	const double *f = st->camera_forward, *r = st->camera_right, *u = st->camera_up;
	double vfov = st->camera_vfov_rad, aspect = st->camera_aspect;
	if (name) {
		const struct sky_shm_view *vw;
		struct skysample_table t;
		if (skysample_view_from_slot(v->header, v->slot_base, name, &t, &vw) < 0)
			return -ENOENT;
		f = vw->camera_forward, r = vw->camera_right, u = vw->camera_up;
		vfov = vw->camera_vfov_rad, aspect = vw->camera_aspect;
	}
	for (int k = 0; k < 3; k++)
		ret->fwd[k] = f[k], ret->right[k] = r[k], ret->up[k] = u[k];
	ret->tan_half = tan(0.5 * vfov);
	ret->aspect = aspect;
	return 0;
}

/* The direction through screen position (u, v) as aerial.comp makes it. */
static void screen_dir(const struct camera *c, double u, double v, double ret[3])
{
	double x = (2.0 * u - 1.0) * c->tan_half * c->aspect, y = (2.0 * v - 1.0) * c->tan_half, n = 0.0;
	for (int k = 0; k < 3; k++) {
		ret[k] = c->fwd[k] + x * c->right[k] + y * c->up[k];
		n += ret[k] * ret[k];
	}
	for (int k = 0; k < 3; k++)
		ret[k] /= sqrt(n);
}

/* Queries: one in eight inside the sun's disk, one in eight inside the
 * moon's (within 0.9 of the radius: the edge is a step), one in four
 * through the query's screen position of the aerial volume's camera, the
 * rest uniform over the sphere; screen positions and distances (0 to 1.2
 * ranges, the camera and the slices' edges among them) and (altitude, mu)
 * over the shell. */
static void make_queries(const struct sky_shm_state *st, const struct camera *cam, struct query *q)
{
	for (int i = 0; i < N_QUERIES; i++) {
		double d[3];
		q[i].p[0] = (float)rnd();
		q[i].p[1] = (float)rnd();
		if (i % 4 == 3)
			screen_dir(cam, q[i].p[0], q[i].p[1], d);
		else if (i % 8 == 1)
			near_dir(st->sun_direction, 0.9 * rnd() * st->sun_angular_radius_rad, d);
		else if (i % 8 == 2)
			near_dir(st->moon_direction, 0.9 * rnd() * st->moon_angular_radius_rad, d);
		else
			skysample_direction(asin(2.0 * rnd() - 1.0), 2.0 * SKYMAP_PI * rnd(), d);
		for (int k = 0; k < 3; k++)
			q[i].dir[k] = (float)d[k];
		double range = st->aerial_range_km;
		q[i].dir[3] = (float)(i % 16 == 3 ? 0.0 : i % 16 == 5 ? range : 1.2 * range * rnd());
		q[i].p[2] = (float)((st->top_radius_km - st->bottom_radius_km) * rnd());
		q[i].p[3] = (float)(2.0 * rnd() - 1.0);
	}
}

/* The spread of channel c over the texels around where skysample_bilinear
 * reads (u, v) in slice k: the cell and one texel beyond each side. */
static double spread_slices(const struct skysample_table *t, double u, double v, uint32_t k0,
			    uint32_t k1, int wrap_u, int c)
{
	uint32_t i0, i1, j0, j1;
	double fu, fv, lo = INFINITY, hi = -INFINITY, px[4];
	skysample_axis(u, t->width, wrap_u, &i0, &i1, &fu);
	skysample_axis(v, t->height, 0, &j0, &j1, &fv);
	for (uint32_t k = k0; k <= k1; k++)
		for (int di = -1; di <= 2; di++)
			for (int dj = -1; dj <= 2; dj++) {
				long i = (long)i0 + di, j = (long)j0 + dj;
				if (wrap_u)
					i = (i + t->width) % t->width;
				if (i < 0 || j < 0 || i >= t->width || j >= t->height)
					continue;
				skysample_texel(t, (uint32_t)i, (uint32_t)j, k, px);
				lo = fmin(lo, px[c]);
				hi = fmax(hi, px[c]);
			}
	return hi - lo;
}

static double spread(const struct skysample_table *t, double u, double v, uint32_t k, int wrap_u, int c)
{
	return spread_slices(t, u, v, k, k, wrap_u, c);
}

struct tally {
	const char *what;
	double worst;		/* error over tolerance */
	double rel;		/* the largest error relative to the value */
	double largest;		/* the largest value */
	int failed;
};

static void expect(struct tally *t, const char *mode, int q, int c, double gpu, double cpu, double tol)
{
	double e = fabs(gpu - cpu) / tol;
	test_checks++;
	if (!(e <= t->worst))
		t->worst = e;
	if (cpu != 0.0)
		t->rel = fmax(t->rel, fabs(gpu - cpu) / fabs(cpu));
	t->largest = fmax(t->largest, fabs(cpu));
	if (e <= 1.0)
		return;
	test_failures++;
	if (t->failed++ < 3)
		fprintf(stderr, "FAIL: %s (%s): query %d channel %d: GPU %.9g, libsky %.9g, tolerance %.3g\n",
			t->what, mode, q, c, gpu, cpu, tol);
}

struct tables {
	struct skysample_table t[SKY_SHM_MAX_TABLES];
};

/* What the texture units' result of a float16 table may lose: its
 * rounding to binary16 (one ulp, 2^-10 of the value at most), which a
 * GPU may do after filtering (an NVIDIA H100 does); 0 for float32 and the
 * exact filter. */
static double half_result(const struct skysample_table *t, double x, int exact)
{
	return !exact && t->format == SKY_FORMAT_RGBA16F ? ldexp(fabs(x), -10) : 0.0;
}

/* The tolerance of a 2-D lookup in t whose texels spread by s, of value x. */
static double tol2(const struct skysample_table *t, double s, double x, int exact)
{
	return (exact ? 1.0 : 2.0) * s / 256.0 + REL_TOL * fabs(x) + half_result(t, x, exact) + 1e-30;
}

/* How far, in texels along u and v, the float direction of the GPU may
 * move a panorama lookup: the azimuth and elevation moved by their float
 * error (atan of components rounded to float, asin near +-1) and mapped
 * again. */
static void panorama_slack(const struct sky_shm_panorama *p, const struct skysample_table *t,
			   const double d[3], double ret_texels[2])
{
	double hz = hypot(d[0], d[1]), az = atan2(d[0], d[1]), el = asin(fmax(-1.0, fmin(1.0, d[2])));
	double daz = fmin(3e-7 + 1.2e-7 / fmax(hz, 1e-30), SKYMAP_PI);
	double del = 3e-7 + fmin(6e-8 / sqrt(fmax(1.0 - d[2] * d[2], 1e-30)), 3.5e-4);
	double u0, v0, u, v;
	ret_texels[0] = ret_texels[1] = 0.0;
	skymap_panorama_uv(p->azimuth0_rad, p->azimuth_step_rad, p->row0, p->row_step, p->horizon_rad,
			   t->width, t->height, p->full_circle != 0, az, el, &u0, &v0);
	for (int s = -1; s <= 1; s += 2) {
		skymap_panorama_uv(p->azimuth0_rad, p->azimuth_step_rad, p->row0, p->row_step,
				   p->horizon_rad, t->width, t->height, p->full_circle != 0, az + s * daz,
				   el + s * del, &u, &v);
		ret_texels[0] = fmax(ret_texels[0], fabs(u - u0) * t->width);
		ret_texels[1] = fmax(ret_texels[1], fabs(v - v0) * t->height);
	}
}

/* sky_aerial_dir (result 8) against sky_sample_view_aerial_dir: vw the
 * view's entry (NULL: the state's camera), ae its texture's texels. */
static void compare_dir(const struct sky_view *v, const struct skysample_table *ae,
			const char *view_name, const struct sky_shm_view *vw, const struct query *q,
			const float *res, int exact, struct tally *tl)
{
	const struct sky_shm_state *st = &v->slot->state;
	const char *mode = exact ? "exact filter" : "texture units";
	const struct sky_shm_panorama *p = vw && vw->form == SKY_VIEW_PANORAMA ? &vw->panorama : NULL;
	struct camera cam;
	CHECK(camera_of(v, view_name, &cam) == 0);
	for (int i = 0; i < N_QUERIES; i++) {
		const float *o = res + 4 * RESULTS_PER_QUERY * i + 32;
		double d[3] = { q[i].dir[0], q[i].dir[1], q[i].dir[2] }, rgb[3], t, u, w;
		double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
		for (int k = 0; k < 3; k++)
			d[k] /= n;
		CHECK(sky_sample_view_aerial_dir(v, view_name, d, q[i].dir[3], rgb, &t) == 0);
		double sl = skymap_aerial_slice(q[i].dir[3], ae->depth, st->aerial_range_km,
						st->aerial_squared != 0);
		uint32_t k0 = sl <= 0.0 ? 0 : (uint32_t)fmin(floor(sl), ae->depth - 1);
		uint32_t k1 = k0 + 1 < ae->depth ? k0 + 1 : k0;
		if (p) {
			double slack[2];
			skymap_panorama_uv(p->azimuth0_rad, p->azimuth_step_rad, p->row0, p->row_step,
					   p->horizon_rad, ae->width, ae->height, p->full_circle != 0,
					   atan2(d[0], d[1]), asin(fmax(-1.0, fmin(1.0, d[2]))), &u, &w);
			panorama_slack(p, ae, d, slack);
			double f = (exact ? 1.0 : 3.0) / 256.0 + slack[0] + slack[1];
			for (int c = 0; c < 4; c++) {
				double x = c < 3 ? rgb[c] : t;
				double s = spread_slices(ae, u, w, k0, k1, 0, c);
				double tol = c < 3 ? fabs(x) * expm1(f * s + 2e-6) : f * s + REL_TOL;
				expect(&tl[7], mode, i, c, o[c], x, tol + 1e-30);
			}
			continue;
		}
		skysample_screen_uv(cam.fwd, cam.right, cam.up, cam.tan_half, cam.aspect, d, &u, &w);
		for (int c = 0; c < 4; c++) {
			double x = c < 3 ? rgb[c] : t;
			double s = spread_slices(ae, u, w, k0, k1, 0, c);
			if (sl <= 0.0) {	/* toward (0, 0, 0, 1) at the camera */
				double px[4];
				skysample_bilinear(ae, u, w, 0, 0, px);
				s = fmax(s, fabs(px[c] - (c < 3 ? 0.0 : 1.0)));
			}
			expect(&tl[7], mode, i, c, o[c], x,
			       (exact ? 1.0 : 3.0) * s / 256.0 + REL_TOL * fabs(x) +
				       half_result(ae, x, exact) + 1e-30);
		}
	}
}

static void compare(const struct sky_view *v, const struct tables *tb, const char *view_name,
		    const struct sky_shm_view *vw, const struct query *q, const float *res, int exact,
		    struct tally *tl)
{
	const struct sky_shm_state *st = &v->slot->state;
	const char *mode = exact ? "exact filter" : "texture units";
	const struct skysample_table *tr = &tb->t[SKY_TABLE_TRANSMITTANCE], *ms = &tb->t[SKY_TABLE_MULTISCATTER],
				     *sv = &tb->t[SKY_TABLE_SKYVIEW], *ae = &tb->t[SKY_TABLE_AERIAL];
	double hc = skymap_horizon_cos(st->bottom_radius_km, st->altitude_km);
	for (int i = 0; i < N_QUERIES; i++) {
		const float *o = res + 4 * RESULTS_PER_QUERY * i;
		double d[3] = { q[i].dir[0], q[i].dir[1], q[i].dir[2] };
		double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
		double el = asin(fmax(-1.0, fmin(1.0, d[2] / n))), az = atan2(d[0], d[1]);
		double rgb[3], with[3], u, w;

		/* Sky radiance, then the disks as sky_sample_sky adds them. */
		CHECK(sky_sample_sky(v, el / (SKYMAP_PI / 180), az / (SKYMAP_PI / 180), 0, rgb) == 0);
		skymap_skyview_uv(hc, 0.5 * SKYMAP_PI - el, az, sv->height, &u, &w);
		for (int c = 0; c < 3; c++)
			expect(&tl[0], mode, i, c, o[c], rgb[c], tol2(sv, spread(sv, u, w, 0, 1, c), rgb[c], exact));
		CHECK(sky_sample_sky(v, el / (SKYMAP_PI / 180), az / (SKYMAP_PI / 180),
				     SKY_SAMPLE_SUN_DISK | SKY_SAMPLE_MOON_DISK | SKY_SAMPLE_LIMB_DARKENING,
				     with) == 0);
		const double *light = i % 8 == 2 ? st->moon_direction : st->sun_direction;
		skymap_transmittance_uv(st->bottom_radius_km, st->top_radius_km, st->altitude_km, light[2],
					tr->width, tr->height, &u, &w);
		for (int c = 0; c < 3; c++) {
			double disk = with[c] - rgb[c], t_light[3];
			skysample_light_transmittance(tr, st, light, t_light);
			double per_t = t_light[c] > 0.0 ? disk / t_light[c] : 0.0;
			expect(&tl[1], mode, i, c, o[4 + c], disk,
			       per_t * tol2(tr, spread(tr, u, w, 0, 0, c), t_light[c], exact) + 1e-4 * disk + 1e-30);
		}

		/* Transmittance toward the direction (0 below the horizon),
		 * and at the query's (altitude, mu). */
		skysample_light_transmittance(tr, st, d, rgb);
		skymap_transmittance_uv(st->bottom_radius_km, st->top_radius_km, st->altitude_km, d[2],
					tr->width, tr->height, &u, &w);
		for (int c = 0; c < 3; c++)
			if (fabs(d[2] - hc) > 1e-6)	/* the horizon's step itself */
				expect(&tl[2], mode, i, c, o[8 + c], rgb[c],
				       tol2(tr, spread(tr, u, w, 0, 0, c), rgb[c], exact));
		CHECK(sky_sample_transmittance(v, q[i].p[2], q[i].p[3], rgb) == 0);
		skymap_transmittance_uv(st->bottom_radius_km, st->top_radius_km, q[i].p[2], q[i].p[3],
					tr->width, tr->height, &u, &w);
		for (int c = 0; c < 3; c++)
			expect(&tl[2], mode, i, c, o[12 + c], rgb[c],
			       tol2(tr, spread(tr, u, w, 0, 0, c), rgb[c], exact));

		/* Aerial perspective: two slices (and the camera's (0, 1)); a
		 * panorama is read by direction only (compare_dir). */
		double t_ae;
		if (vw && vw->form == SKY_VIEW_PANORAMA)
			t_ae = 0.0;
		else if (view_name)
			CHECK(sky_sample_view_aerial(v, view_name, q[i].p[0], q[i].p[1], q[i].dir[3], rgb,
						     &t_ae) == 0);
		else
			CHECK(sky_sample_aerial(v, q[i].p[0], q[i].p[1], q[i].dir[3], rgb, &t_ae) == 0);
		double sl = skymap_aerial_slice(q[i].dir[3], ae->depth, st->aerial_range_km,
						st->aerial_squared != 0);
		uint32_t k0 = sl <= 0.0 ? 0 : (uint32_t)fmin(floor(sl), ae->depth - 1);
		uint32_t k1 = k0 + 1 < ae->depth ? k0 + 1 : k0;
		for (int c = 0; c < 4 && !(vw && vw->form == SKY_VIEW_PANORAMA); c++) {
			double x = c < 3 ? rgb[c] : t_ae;
			double s = spread_slices(ae, q[i].p[0], q[i].p[1], k0, k1, 0, c);
			if (sl <= 0.0) {	/* toward (0, 0, 0, 1) at the camera */
				double px[4];
				skysample_bilinear(ae, q[i].p[0], q[i].p[1], 0, 0, px);
				s = fmax(s, fabs(px[c] - (c < 3 ? 0.0 : 1.0)));
			}
			expect(&tl[3], mode, i, c, o[16 + c], x,
			       (exact ? 1.0 : 3.0) * s / 256.0 + REL_TOL * fabs(x) +
				       half_result(ae, x, exact) + 1e-30);
		}

		/* The multi-scattering table, as skysample.h reads a table. */
		double px[4];
		skymap_multiscatter_uv(st->bottom_radius_km, st->top_radius_km, q[i].p[2], q[i].p[3],
				       ms->width, ms->height, &u, &w);
		skysample_bilinear(ms, u, w, 0, 0, px);
		for (int c = 0; c < 4; c++)
			expect(&tl[4], mode, i, c, o[20 + c], px[c], tol2(ms, spread(ms, u, w, 0, 0, c), px[c], exact));

		/* The lights' illuminance: sky_sample_sun, and the moon's alike. */
		const double *dir = i % 2 == 0 ? st->sun_direction : st->moon_direction;
		const double *lx = i % 2 == 0 ? st->sun_illuminance_lx : st->moon_illuminance_lx;
		double t_l[3];
		if (i % 2 == 0)
			CHECK(sky_sample_sun(v, rgb) == 0);
		skysample_light_transmittance(tr, st, dir, t_l);
		skymap_transmittance_uv(st->bottom_radius_km, st->top_radius_km, st->altitude_km, dir[2],
					tr->width, tr->height, &u, &w);
		for (int c = 0; c < 3; c++) {
			double x = i % 2 == 0 ? rgb[c] : lx[c] * t_l[c];
			expect(&tl[5], mode, i, c, o[24 + c], x,
			       lx[c] * tol2(tr, spread(tr, u, w, 0, 0, c), t_l[c], exact) + 1e-30);
		}

		/* The screen position of a direction made from one: float
		 * rounding of the direction and the camera, about 1e-6. */
		if (i % 16 == 7 && !(vw && vw->form == SKY_VIEW_PANORAMA))
			for (int c = 0; c < 2; c++)
				expect(&tl[6], mode, i, c, o[28 + c], q[i].p[c], 1e-5);
	}
	compare_dir(v, ae, view_name, vw, q, res, exact, tl);
}

/* sky_gpu_state's panorama fields: the entry's, rounded to float, for a
 * view of form panorama (form 1 an arc, 2 the full circle); 0 else. */
static void check_state_panorama(const struct sky_gpu_state *st, const struct sky_shm_view *vw)
{
	if (!vw || vw->form != SKY_VIEW_PANORAMA) {
		for (int k = 0; k < 4; k++)
			CHECK(st->panorama[k] == 0.0f && st->panorama_grid[k] == 0.0f);
		return;
	}
	const struct sky_shm_panorama *p = &vw->panorama;
	CHECK(st->panorama[0] == (float)p->azimuth0_rad && st->panorama[1] == (float)p->azimuth_step_rad &&
	      st->panorama[2] == (float)p->row0 && st->panorama[3] == (float)p->row_step);
	CHECK(st->panorama_grid[0] == (float)p->horizon_rad && st->panorama_grid[1] == (float)p->width &&
	      st->panorama_grid[2] == (float)p->height &&
	      st->panorama_grid[3] == (p->full_circle ? 2.0f : 1.0f));
	CHECK(st->camera_forward[0] == (float)vw->camera_forward[0] &&
	      st->camera_up[2] == (float)vw->camera_up[2]);
}

/* Uploads the snapshot's tables as a client does, from sky_gpu_tables(),
 * and runs both builds of the shader; compares each with libsky. */
static void run_generation(struct gvk *g, const struct sky_view *v, const struct sky_gpu_table *gt,
			   const char *view_name)
{
	int mark_b = g->n_buffers, mark_i = g->n_images;
	struct sky_gpu_state st;
	struct tables tb;
	struct camera cam = { { 0 }, { 0 }, { 0 }, 1.0, 1.0 };
	const struct sky_shm_view *vw = NULL;
	CHECK(sky_gpu_state(v, "no-such-view", &st) == -ENOENT);
	CHECK(sky_gpu_state(v, view_name, &st) == 0);
	CHECK(camera_of(v, view_name, &cam) == 0);
	if (view_name)
		CHECK(skysample_view_from_slot(v->header, v->slot_base, view_name, &tb.t[SKY_TABLE_AERIAL],
					       &vw) == 0);
	check_state_panorama(&st, vw);
	struct gvk_image *im[SKY_SHM_MAX_TABLES];
	/* The sky's four tables; a clear sky has no cloud table. */
	for (uint32_t id = 0; id <= SKY_TABLE_AERIAL; id++) {
		CHECK(gt[id].present && gt[id].id == id);
		if (id != SKY_TABLE_AERIAL || !view_name)	/* else the view's, above */
			CHECK(skysample_table_from_slot(v->header, v->slot_base, id, &tb.t[id]) == 0);
		CHECK(gt[id].texels == tb.t[id].texels);
		CHECK(gt[id].bytes == (uint64_t)gt[id].width * gt[id].height * gt[id].depth * gt[id].texel_bytes);
		VkFormat f = (VkFormat)gt[id].vk_format;
		CHECK(f == (gt[id].format == SKY_FORMAT_RGBA16F ? VK_FORMAT_R16G16B16A16_SFLOAT
							       : VK_FORMAT_R32G32B32A32_SFLOAT));
		if (!gvk_linear_ok(g, f)) {
			printf("skipped: %s cannot filter format %u linearly\n", g->device_name, (unsigned)f);
			exit(77);
		}
		im[id] = gvk_image_new(g, f, gt[id].width, gt[id].height, gt[id].depth, gt[id].texels,
				       gt[id].bytes, id == SKY_TABLE_SKYVIEW, id == SKY_TABLE_AERIAL);
	}
	struct gvk_buffer *ubo = gvk_buffer_new(g, sizeof(st), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT);
	memcpy(ubo->map, &st, sizeof(st));
	struct gvk_buffer *qb = gvk_buffer_new(g, sizeof(struct query) * N_QUERIES,
					       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	struct gvk_buffer *rb = gvk_buffer_new(g, 16 * RESULTS_PER_QUERY * N_QUERIES,
					       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
	make_queries(&v->slot->state, &cam, qb->map);
	struct gvk_binding b[7] = {
		{ VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, ubo, NULL },
		{ VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, NULL, im[SKY_TABLE_TRANSMITTANCE] },
		{ VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, NULL, im[SKY_TABLE_MULTISCATTER] },
		{ VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, NULL, im[SKY_TABLE_SKYVIEW] },
		{ VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, NULL, im[SKY_TABLE_AERIAL] },
		{ VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, qb, NULL },
		{ VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, rb, NULL },
	};
	for (int exact = 0; exact <= 1; exact++) {
		struct tally tl[] = { { "sky radiance", 0, 0, 0, 0 }, { "disks", 0, 0, 0, 0 },
				      { "transmittance", 0, 0, 0, 0 }, { "aerial", 0, 0, 0, 0 },
				      { "multiscatter", 0, 0, 0, 0 }, { "sun/moon illuminance", 0, 0, 0, 0 },
				      { "aerial screen uv", 0, 0, 0, 0 }, { "aerial by direction", 0, 0, 0, 0 } };
		memset(rb->map, 0xff, rb->bytes);	/* NaN: a result not written fails */
		if (exact)
			gvk_dispatch(g, glsl_sample_exact_spv, sizeof(glsl_sample_exact_spv), b, 7,
				     (N_QUERIES + 63) / 64);
		else
			gvk_dispatch(g, glsl_sample_hw_spv, sizeof(glsl_sample_hw_spv), b, 7,
				     (N_QUERIES + 63) / 64);
		compare(v, &tb, view_name, vw, qb->map, rb->map, exact, tl);
		printf("generation %u, %s, %s, aerial of %s (worst error / tolerance, largest relative "
		       "error, largest value):\n", v->generation,
		       gt[0].format == SKY_FORMAT_RGBA16F ? "float16" : "float32",
		       exact ? "exact filter" : "texture units", view_name ? view_name : "the state's camera");
		if (vw && vw->form == SKY_VIEW_PANORAMA)
			printf("  (a panorama of %u x %u x %u, %s)\n", vw->panorama.width, vw->panorama.height,
			       vw->panorama.depth, vw->panorama.full_circle ? "the full circle" : "an arc");
		for (size_t k = 0; k < sizeof(tl) / sizeof(tl[0]); k++)
			printf("  %-22s %.3f  %.2e  %.4g\n", tl[k].what, tl[k].worst, tl[k].rel, tl[k].largest);
	}
	gvk_release_to(g, mark_b, mark_i);
}

/* Waits until the newest slot has generation >= gen, every table valid,
 * in format fmt, and copies it into a buffer of its own (the slot's size
 * changes with the region), which the caller frees; NULL on failure. */
static void *snapshot_at(sky_client *c, uint32_t gen, uint32_t fmt, struct sky_view *ret)
{
	for (int i = 0; i < 1000; i++) {
		size_t size = (sky_snapshot_size(c) + 63) / 64 * 64;
		void *buf = size ? aligned_alloc(64, size) : NULL;
		if (!buf || sky_snapshot(c, buf, size, ret) < 0) {
			free(buf);
			return NULL;
		}
		if (ret->slot->generation >= gen && ret->valid_tables == SKY_TABLES_ALL &&
		    ret->header->tables[0].format == fmt)
			return buf;
		free(buf);
		struct sky_event ev;
		while (sky_dispatch(c, &ev) == 1)
			;
		if (sky_wait(c, ret->generation, 30000, NULL) < 0)
			return NULL;
	}
	return NULL;
}


/* sky_gpu_view_table()'s description of view name: the aerial table's
 * format and sizes for a volume; for a panorama, RGBA32F unscaled with the
 * panorama's sizes and texels (sky_view_aerial_table()'s). */
static void check_view_table(const struct sky_view *v, const char *name, const struct sky_gpu_table *vt,
			     const struct sky_gpu_table *aerial)
{
	const struct sky_shm_view *vw;
	struct skysample_table t;
	const void *texels;
	size_t bytes;
	CHECK(skysample_view_from_slot(v->header, v->slot_base, name, &t, &vw) == 0);
	CHECK(sky_view_aerial_table(v, name, &texels, &bytes) == 0 && texels == vt->texels &&
	      bytes == vt->bytes);
	CHECK(vt->id == SKY_TABLE_AERIAL && vt->width == t.width && vt->height == t.height &&
	      vt->depth == t.depth && vt->bytes == (uint64_t)t.width * t.height * t.depth * vt->texel_bytes);
	if (vw->form != SKY_VIEW_PANORAMA) {
		CHECK(vt->bytes == aerial->bytes && vt->format == aerial->format &&
		      vt->width == aerial->width && vt->depth == aerial->depth);
		return;
	}
	const struct sky_shm_panorama *p = &vw->panorama;
	CHECK(vt->format == SKY_FORMAT_RGBA32F && vt->vk_format == SKY_VK_FORMAT_R32G32B32A32_SFLOAT &&
	      vt->texel_bytes == 16 && vt->rgb_scale_log2 == 0 && vt->row_pitch_bytes == 16ull * p->width &&
	      vt->slice_pitch_bytes == 16ull * p->width * p->height);
	CHECK(vt->width == p->width && vt->height == p->height && vt->depth == p->depth &&
	      vt->bytes == p->bytes && vt->texels == (const char *)v->slot_base + p->offset);
	CHECK(p->width >= 2 && p->height >= 2 && p->depth == aerial->depth);
	if (p->full_circle) {	/* the last column repeats the first */
		double worst = 0.0;
		for (uint32_t k = 0; k < p->depth; k++)
			for (uint32_t j = 0; j < p->height; j++) {
				double a[4], b[4];
				skysample_texel(&t, 0, j, k, a);
				skysample_texel(&t, p->width - 1, j, k, b);
				for (int ch = 0; ch < 4; ch++)
					worst = fmax(worst, fabs(a[ch] - b[ch]));
			}
		printf("full circle: first and last columns differ by %.3g at most (log-RGB, A)\n", worst);
		CHECK(worst == 0.0);
	}
}

/* Takes the generation at least gen in format fmt, checks which tables
 * sky_gpu_tables() says changed in it (mask), and runs it. */
static void step(struct gvk *g, sky_client *c, uint32_t gen, uint32_t fmt, uint32_t changed_mask,
		 const uint32_t before[SKY_SHM_MAX_TABLES], uint32_t ret_changed[SKY_SHM_MAX_TABLES],
		 const char *view_name, int view_changed)
{
	struct sky_view v;
	struct sky_gpu_table gt[SKY_SHM_MAX_TABLES];
	void *buf = snapshot_at(c, gen, fmt, &v);
	if (!buf) {
		FAIL("no generation %u in format %u", gen, fmt);
		memset(ret_changed, 0, SKY_SHM_MAX_TABLES * sizeof(ret_changed[0]));
		return;
	}
	/* The slot's checksum, views and panoramas included, as skyd sums it. */
	CHECK(sky_view_verify(&v));
	int mask = sky_gpu_tables(c, &v, gt);
	CHECK(mask == (int)changed_mask);
	for (uint32_t id = 0; id < SKY_SHM_MAX_TABLES; id++) {
		uint32_t want = (changed_mask & SKY_TABLE_BIT(id)) ? v.generation : before[id];
		if (gt[id].changed_generation != want)
			FAIL("table %u: changed_generation %u, expected %u", id, gt[id].changed_generation, want);
		ret_changed[id] = gt[id].changed_generation;
	}
	/* A second call in the same generation reports the same. */
	struct sky_gpu_table again[SKY_SHM_MAX_TABLES];
	CHECK(sky_gpu_tables(c, &v, again) == mask);
	CHECK(memcmp(again, gt, sizeof(gt)) == 0);
	/* A zero-copy view of the same generation: the same contents, the
	 * texels in the mapping at map_offset. */
	struct sky_view zv;
	if (sky_view_begin(c, &zv) == 0 && zv.generation == v.generation) {
		int r = sky_gpu_tables(c, &zv, again);
		if (sky_view_end(c, &zv) && r >= 0) {
			CHECK(r == mask);
			for (uint32_t id = 0; id <= SKY_TABLE_AERIAL; id++) {
				CHECK(again[id].changed_generation == gt[id].changed_generation);
				CHECK(again[id].map_offset % 64 == 0 && again[id].map_offset > 0);
				CHECK((const char *)zv.header + again[id].map_offset == again[id].texels);
				CHECK(memcmp(again[id].texels, gt[id].texels, gt[id].bytes) == 0);
			}
		}
	}
	/* The view's volume, uploaded in place of the aerial table: it
	 * changed in this generation (the view is new or moved). */
	struct sky_gpu_table vt;
	if (view_name) {
		int vr = sky_gpu_view_table(c, &v, view_name, &vt);
		CHECK(view_changed < 0 ? vr == 0 || vr == 1 : vr == view_changed);
		CHECK(vt.present && (vr == 0 || vt.changed_generation == v.generation));
		check_view_table(&v, view_name, &vt, &gt[SKY_TABLE_AERIAL]);
		CHECK(sky_gpu_view_table(c, &v, view_name, &vt) == vr);
		CHECK(sky_gpu_view_table(c, &v, "no-such-view", &vt) == -ENOENT);
		CHECK(sky_gpu_view_table(c, &v, view_name, &gt[SKY_TABLE_AERIAL]) == vr);
	}
	run_generation(g, &v, gt, view_name);
	free(buf);
}

/* Views of form panorama on the wall's eye point: one (an arc of
 * azimuths; run with the volume view beside it), then four all round, one
 * with the zenith in its frustum (the full circle). */
static void panorama_steps(struct gvk *g, sky_client *c, const uint32_t before[SKY_SHM_MAX_TABLES])
{
	uint32_t seen[SKY_SHM_MAX_TABLES], again[SKY_SHM_MAX_TABLES];
	uint32_t gen = set_and_generation(c, "view add name=pano form=panorama altitude_km=1.5 yaw_deg=200 pitch_deg=4 vfov_deg=50 aspect=2");
	step(g, c, gen, SKY_FORMAT_RGBA16F, 0, before, seen, "pano", 1);
	step(g, c, gen, SKY_FORMAT_RGBA16F, 0, seen, again, "wall", -1);
	static const char *const all_round[] = {
		"view add name=pano form=panorama altitude_km=1.5 yaw_deg=0 vfov_deg=50 aspect=3",
		"view add name=pano2 form=panorama altitude_km=1.5 yaw_deg=90 vfov_deg=50 aspect=3",
		"view add name=pano3 form=panorama altitude_km=1.5 yaw_deg=180 vfov_deg=50 aspect=3",
	};
	for (size_t k = 0; k < sizeof(all_round) / sizeof(all_round[0]); k++)
		gen = set_and_generation(c, all_round[k]);
	gen = set_and_generation(c, "view add name=pano4 form=panorama altitude_km=1.5 yaw_deg=270 pitch_deg=75 vfov_deg=50 aspect=3");
	step(g, c, gen, SKY_FORMAT_RGBA16F, 0, again, seen, "pano3", 1);
	/* Described for each view alike: the same texels, all changed in this
	 * generation (pano3's recorded by step, the others new or widened). */
	struct sky_view v;
	void *buf = snapshot_at(c, gen, SKY_FORMAT_RGBA16F, &v);
	CHECK(buf != NULL);
	const char *const walls[] = { "pano", "pano2", "pano3", "pano4" };
	struct sky_gpu_table vt[4];
	for (int k = 0; buf && k < 4; k++) {
		CHECK(sky_gpu_view_table(c, &v, walls[k], &vt[k]) == 1);
		CHECK(vt[k].texels == vt[0].texels && vt[k].bytes == vt[0].bytes &&
		      vt[k].changed_generation == v.generation);
	}
	free(buf);
	/* A view on another eye point: a new generation in which this eye
	 * point's panorama holds the same bytes, which no view reports as
	 * changed (views that share a panorama share its hash). */
	uint32_t was = v.generation;
	gen = set_and_generation(c, "view add name=far altitude_km=3 yaw_deg=10");
	buf = snapshot_at(c, gen, SKY_FORMAT_RGBA16F, &v);
	CHECK(buf != NULL && v.generation > was);
	for (int k = 0; buf && k < 4; k++)
		CHECK(sky_gpu_view_table(c, &v, walls[k], &vt[k]) == 0 && vt[k].changed_generation == was);
	free(buf);
	/* One eye point, one panorama: every view of that form reads the same
	 * texels, and with the zenith in a view they go all round. */
	if (sky_view_begin(c, &v) == 0) {
		const void *t1 = NULL, *tk = NULL;
		const char *names[] = { "pano2", "pano3", "pano4" };
		const struct sky_shm_view *vw = NULL;
		struct skysample_table t;
		CHECK(sky_view_aerial_table(&v, "pano", &t1, NULL) == 0);
		for (int k = 0; k < 3; k++)
			CHECK(sky_view_aerial_table(&v, names[k], &tk, NULL) == 0 && tk == t1);
		CHECK(skysample_view_from_slot(v.header, v.slot_base, "pano", &t, &vw) == 0 &&
		      vw->form == SKY_VIEW_PANORAMA && vw->panorama.full_circle == 1);
		CHECK(sky_view_end(c, &v));
	}
}

int main(void)
{
	struct daemon d = { 0 };
	struct gvk g;
	harness_need_device();
	if (gvk_open(&g) < 0) {
		printf("skipped: no Vulkan device for the client\n");
		return 77;
	}
	printf("device: %s\n", g.device_name);
	if (daemon_start(&d, args) < 0) {
		FAIL("skyd did not start");
		gvk_close(&g);
		return test_report("test_glsl_sample");
	}
	sky_client *c = NULL;
	CHECK(sky_connect(d.sock, &c) == 0);
	if (c) {
		uint32_t none[SKY_SHM_MAX_TABLES] = { 0 }, first[SKY_SHM_MAX_TABLES], second[SKY_SHM_MAX_TABLES],
			 third[SKY_SHM_MAX_TABLES], fourth[SKY_SHM_MAX_TABLES], fifth[SKY_SHM_MAX_TABLES];
		sky_set_timeout(c, 60000);
		CHECK(sky_subscribe(c, SKY_TABLES_ALL, 0) == 0);
		step(&g, c, 0, SKY_FORMAT_RGBA32F, SKY_TABLES_ALL, none, first, NULL, 0);
		uint32_t gen = set_and_generation(c, "set storage=f16");
		step(&g, c, gen, SKY_FORMAT_RGBA16F, SKY_TABLES_ALL, first, second, NULL, 0);
		gen = set_and_generation(c, "set sun_elevation_deg=25");
		step(&g, c, gen, SKY_FORMAT_RGBA16F,
		     SKY_TABLE_BIT(SKY_TABLE_SKYVIEW) | SKY_TABLE_BIT(SKY_TABLE_AERIAL), second, third, NULL, 0);
		/* A view: a new region (every table counts as changed), then
		 * the view moved: the state's aerial table is recomputed with
		 * the same bytes and is not reported, the view's volume is. The
		 * view's eye is not the camera's: views on one eye point share
		 * one march, and the camera's volume would follow the panorama
		 * the moved view widens (PROTOCOL.md, "Views on one eye point"). */
		gen = set_and_generation(c, "view add name=wall altitude_km=1.5 yaw_deg=200 pitch_deg=4 vfov_deg=50 aspect=2");
		step(&g, c, gen, SKY_FORMAT_RGBA16F, SKY_TABLES_ALL, third, fourth, "wall", 1);
		gen = set_and_generation(c, "view add name=wall altitude_km=1.5 yaw_deg=80 pitch_deg=-3 vfov_deg=35 aspect=1.5");
		step(&g, c, gen, SKY_FORMAT_RGBA16F, 0, fourth, fifth, "wall", 1);
		panorama_steps(&g, c, fifth);
		sky_disconnect(c);
	}
	daemon_cleanup(&d);
	gvk_close(&g);
	return test_report("test_glsl_sample");
}
