/* test_skysample_panorama.c - the CPU reading of views of form panorama
 * (proto/skysample.h and libsky) on a hand-built slot whose answers are
 * known exactly: panoramas whose log-radiance and transmittance are linear
 * in the texel indices, which trilinear filtering in log-RGB and linear A
 * reproduces exactly at any direction and distance. Directions are made
 * from column and row coordinates by inverting the mapping's definition
 * (azimuth0 + f step; elevation = horizon + x |x|, x = row0 + g row_step),
 * not with skymap_panorama_uv, so a mapping that moves fails here. Also
 * the entry checks, the checksum rule (a panorama once per view, even
 * shared) and libsky's view functions on both forms. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sky.h"
#include "skysample.h"
#include "test.h"

#define PI SKYMAP_PI
#define TWO_PI (2.0 * SKYMAP_PI)

enum { AW = 6, AH = 5, AD = 4 };		/* the aerial table and view volumes */
enum { PW = 16, PH = 10, PD = 6 };		/* the arc panorama */
enum { RW = 9, RH = 7, RD = 5 };		/* the full-circle panorama */

/* log L_c = la[c] + lb[c] i + lc[c] j + ld[c] k, A likewise: dyadic
 * coefficients, so that every texel holds the field exactly in float. */
static const double la[3] = { 1.5, -0.5, 2.0 }, lb[3] = { 0.125, -0.0625, 0.03125 },
		    lc[3] = { -0.25, 0.125, 0.0625 }, ld[3] = { 0.375, 0.25, -0.1875 };

static double field_log(int c, double i, double j, double k)
{
	return la[c] + lb[c] * i + lc[c] * j + ld[c] * k;
}

static double field_a(double i, double j, double k)
{
	return 0.875 - 0.0078125 * i - 0.015625 * j - 0.046875 * k;
}

static uint64_t align64(uint64_t x)
{
	return (x + 63) & ~(uint64_t)63;
}

struct region {
	struct sky_shm_header *hdr;
	unsigned char *slot;		/* slot 0 */
	uint64_t arc_offset, ring_offset;
};

static void fill_panorama(float *p, unsigned w, unsigned h, unsigned d)
{
	for (unsigned k = 0; k < d; k++)
		for (unsigned j = 0; j < h; j++)
			for (unsigned i = 0; i < w; i++) {
				float *t = p + (((size_t)k * h + j) * w + i) * 4;
				for (int c = 0; c < 3; c++)
					t[c] = (float)field_log(c, i, j, k);
				t[3] = (float)field_a(i, j, k);
			}
}

static void camera(struct sky_shm_view *v, double yaw_rad, double vfov_rad, double aspect)
{
	double f[3] = { sin(yaw_rad), cos(yaw_rad), 0.0 }, r[3] = { cos(yaw_rad), -sin(yaw_rad), 0.0 };
	for (int k = 0; k < 3; k++) {
		v->camera_forward[k] = f[k];
		v->camera_right[k] = r[k];
		v->camera_up[k] = k == 2 ? 1.0 : 0.0;
	}
	v->camera_vfov_rad = vfov_rad;
	v->camera_aspect = aspect;
}

/* A header and three slots: the aerial table, 8 view volumes, then the
 * arc panorama and the full-circle one. Views: vol (volume), pano and
 * pano2 (the arc, shared), ring (the full circle). */
static void build(struct region *r)
{
	uint64_t header_bytes = align64(sizeof(struct sky_shm_header));
	uint64_t aerial_bytes = (uint64_t)AW * AH * AD * 16;
	uint64_t aerial_off = align64(sizeof(struct sky_shm_slot));
	uint64_t view_off = align64(aerial_off + aerial_bytes);
	uint64_t stride = align64(aerial_bytes);
	r->arc_offset = view_off + SKY_SHM_MAX_VIEWS * stride;
	r->ring_offset = align64(r->arc_offset + (uint64_t)PW * PH * PD * 16);
	uint64_t slot_bytes = align64(r->ring_offset + (uint64_t)RW * RH * RD * 16);
	uint64_t total = header_bytes + 3 * slot_bytes;
	r->hdr = aligned_alloc(64, total);
	memset(r->hdr, 0, total);
	*r->hdr = (struct sky_shm_header){
		.magic = SKY_SHM_MAGIC, .layout_version = SKY_SHM_LAYOUT_VERSION,
		.header_bytes = (uint32_t)header_bytes, .n_slots = 3, .slot_bytes = slot_bytes,
		.total_bytes = total, .n_tables = 1, .uv_mapping_version = SKYMAP_VERSION,
		.max_views = SKY_SHM_MAX_VIEWS, .view_offset = view_off, .view_stride = stride,
	};
	r->hdr->tables[0] = (struct sky_shm_table){ SKY_TABLE_AERIAL, SKY_FORMAT_RGBA32F, AW, AH, AD,
						    16, aerial_off, aerial_bytes };
	r->slot = (unsigned char *)r->hdr + header_bytes;
	struct sky_shm_slot *s = (struct sky_shm_slot *)r->slot;
	s->state.bottom_radius_km = 6360.0;
	s->state.top_radius_km = 6460.0;
	s->state.aerial_range_km = 32.0;
	s->state.aerial_squared = 1;
	camera(&s->views[0], 0.3, 1.0, 1.5);
	float *vol = (float *)(r->slot + aerial_off);
	for (size_t n = 0; n < (size_t)AW * AH * AD * 4; n++)
		vol[n] = (float)(0.5 + 0.001 * (double)n);
	memcpy(r->slot + view_off, vol, aerial_bytes);
	fill_panorama((float *)(r->slot + r->arc_offset), PW, PH, PD);
	fill_panorama((float *)(r->slot + r->ring_offset), RW, RH, RD);

	s->n_views = 4;
	s->valid_tables = SKY_TABLE_BIT(SKY_TABLE_AERIAL);
	s->valid_views = 0xf;
	snprintf(s->views[0].name, SKY_SHM_VIEW_NAME_MAX, "vol");
	s->views[0].form = SKY_VIEW_VOLUME;
	struct sky_shm_panorama arc = { r->arc_offset, (uint64_t)PW * PH * PD * 16, PW, PH, PD, 0,
					1.0, 0.05, -0.3, 0.08, -0.01 };
	struct sky_shm_panorama ring = { r->ring_offset, (uint64_t)RW * RH * RD * 16, RW, RH, RD, 1,
					 5.0, TWO_PI / (RW - 1), -0.9, 0.25, -0.02 };
	const char *names[] = { "pano", "pano2", "ring" };
	for (int n = 1; n <= 3; n++) {
		snprintf(s->views[n].name, SKY_SHM_VIEW_NAME_MAX, "%s", names[n - 1]);
		s->views[n].form = SKY_VIEW_PANORAMA;
		s->views[n].panorama = n == 3 ? ring : arc;
		camera(&s->views[n], n == 2 ? 1.2 : 1.3, 0.4, 2.0);
	}
	s->checksum = skysample_slot_checksum(r->hdr, s);
}

/* The unit direction at column coordinate f and row coordinate g of p. */
static void dir_at(const struct sky_shm_panorama *p, double f, double g, double ret[3])
{
	double x = p->row0 + g * p->row_step;
	skysample_direction(p->horizon_rad + x * fabs(x), p->azimuth0_rad + f * p->azimuth_step_rad, ret);
}

/* The exact answer at (f, g) and slice coordinate w. */
static void expected(double f, double g, double w, unsigned depth, double ret_rgb[3], double *ret_t)
{
	double wc = skymap_clamp(w, 0.0, depth - 1.0);
	double m = w < 0.0 ? fmax(w + 1.0, 0.0) : 1.0;
	for (int c = 0; c < 3; c++)
		ret_rgb[c] = m * exp(field_log(c, f, g, wc));
	*ret_t = 1.0 + m * (field_a(f, g, wc) - 1.0);
}

static int close_to(const double *a, double at, const double *b, double bt, double rel)
{
	for (int c = 0; c < 3; c++)
		if (!(fabs(a[c] - b[c]) <= rel * fabs(b[c]) + 1e-300))
			return 0;
	return fabs(at - bt) <= rel;
}

static uint64_t rng_state = 0x9a70u;

static double rnd(void)
{
	return test_uniform(&rng_state);
}

/* One direction at (f, g) and a distance: skysample_panorama against the
 * exact field. */
static void check_at(const struct region *r, const char *name, double f, double g, double dist,
		     const char *what)
{
	const struct sky_shm_view *vw;
	struct skysample_table t;
	const struct sky_shm_slot *s = (const struct sky_shm_slot *)r->slot;
	CHECK_EQ(skysample_view_from_slot(r->hdr, r->slot, name, &t, &vw), 0);
	double d[3], rgb[3], tr, want[3], want_t;
	dir_at(&vw->panorama, f, g, d);
	double w = skymap_aerial_slice(dist, t.depth, s->state.aerial_range_km, 1);
	skysample_panorama(&t, &vw->panorama, &s->state, d, dist, rgb, &tr);
	double fc = skymap_clamp(f, 0.0, t.width - 1.0), gc = skymap_clamp(g, 0.0, t.height - 1.0);
	expected(fc, gc, w, t.depth, want, &want_t);
	if (!close_to(rgb, tr, want, want_t, 1e-9))
		FAIL("%s %s at f %.4f g %.4f w %.4f: (%.9g %.9g %.9g; %.9g), expected (%.9g %.9g %.9g; %.9g)",
		     name, what, f, g, w, rgb[0], rgb[1], rgb[2], tr, want[0], want[1], want[2], want_t);
	else
		test_checks++;
}

static void test_sampling(const struct region *r)
{
	const struct sky_shm_slot *s = (const struct sky_shm_slot *)r->slot;
	const struct sky_shm_panorama *arc = &s->views[1].panorama;
	double range = s->state.aerial_range_km;
	/* Inside: any column, row and distance (the eye, the slices, beyond). */
	for (int n = 0; n < 2000; n++) {
		double dist = n % 50 == 0 ? 0.0 : n % 50 == 1 ? 2.0 * range : 1.3 * range * rnd();
		check_at(r, "pano", rnd() * (PW - 1), rnd() * (PH - 1), dist, "inside");
		check_at(r, "ring", rnd() * (RW - 1), rnd() * (RH - 1), dist, "inside");
	}
	/* Rows clamp: above the top row and below the bottom one. */
	check_at(r, "pano", 3.3, PH - 1 + 2.5, 10.0, "above the rows");
	check_at(r, "pano", 7.6, -3.0, 10.0, "below the rows");
	check_at(r, "ring", 2.5, RH - 1 + 0.7, 5.0, "above the rows");
	/* Outside the arc: the nearer end, on either side of the gap's middle. */
	double span = arc->azimuth_step_rad * (PW - 1), gap = TWO_PI - span;
	double step = arc->azimuth_step_rad;
	check_at(r, "pano", PW - 1 + 0.2 / step, 4.5, 12.0, "past the arc's end");
	check_at(r, "pano", -0.2 / step, 4.5, 12.0, "before the arc's start");
	double mid = (PW - 1) + 0.5 * gap / step;
	const struct sky_shm_view *vw;
	struct skysample_table t;
	CHECK_EQ(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, &vw), 0);
	double d[3], rgb[3], tr, want[3], want_t;
	dir_at(arc, mid - 0.01, 4.5, d);
	skysample_panorama(&t, arc, &s->state, d, 12.0, rgb, &tr);
	expected(PW - 1, 4.5, skymap_aerial_slice(12.0, PD, range, 1), PD, want, &want_t);
	CHECK(close_to(rgb, tr, want, want_t, 1e-9));
	dir_at(arc, mid + 0.01, 4.5, d);
	skysample_panorama(&t, arc, &s->state, d, 12.0, rgb, &tr);
	expected(0.0, 4.5, skymap_aerial_slice(12.0, PD, range, 1), PD, want, &want_t);
	CHECK(close_to(rgb, tr, want, want_t, 1e-9));
	/* Across north in the full circle (azimuth0 5 rad, west of north):
	 * north itself, just east of it, and just west of azimuth0 (the last
	 * column, which repeats the first). */
	const struct sky_shm_panorama *ring = &s->views[3].panorama;
	double north_f = (TWO_PI - ring->azimuth0_rad) / ring->azimuth_step_rad;
	check_at(r, "ring", north_f, 3.0, 8.0, "at north");
	check_at(r, "ring", north_f + 0.4, 3.0, 8.0, "east of north");
	check_at(r, "ring", RW - 1 - 0.3, 3.0, 8.0, "west of azimuth0");
	check_at(r, "ring", 0.3, 3.0, 8.0, "east of azimuth0");
	/* At the eye: (0, 0, 0, 1) exactly. */
	dir_at(arc, 3.0, 3.0, d);
	skysample_panorama(&t, arc, &s->state, d, 0.0, rgb, &tr);
	CHECK(rgb[0] == 0.0 && rgb[1] == 0.0 && rgb[2] == 0.0 && tr == 1.0);
}

static void test_entries(struct region *r)
{
	struct sky_shm_slot *s = (struct sky_shm_slot *)r->slot;
	const struct sky_shm_view *vw;
	struct skysample_table t, t2;
	CHECK_EQ(skysample_check_layout(r->hdr, r->hdr->total_bytes), 0);
	CHECK_EQ(skysample_view_from_slot(r->hdr, r->slot, "vol", &t, &vw), 0);
	CHECK(vw == &s->views[0] && t.texels == r->slot + r->hdr->view_offset && t.depth == AD);
	CHECK_EQ(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, &vw), 0);
	CHECK(vw == &s->views[1] && t.texels == r->slot + r->arc_offset &&
	      t.format == SKY_FORMAT_RGBA32F && t.width == PW && t.height == PH && t.depth == PD &&
	      t.rgb_scale_log2 == 0);
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano2", &t2, NULL) == 0 && t2.texels == t.texels);
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "nobody", &t, NULL) == -ENOENT);
	s->valid_views &= ~2u;
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, NULL) == -ENODATA);
	s->valid_views |= 2u;
	/* Entries from a peer that would index outside the slot. */
	struct sky_shm_panorama keep = s->views[1].panorama;
	struct sky_shm_panorama *p = &s->views[1].panorama;
	p->offset = r->hdr->slot_bytes - p->bytes + 64;
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, NULL) == -EPROTO);
	p->offset = UINT64_MAX - 8;
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, NULL) == -EPROTO);
	*p = keep;
	p->offset = 64;			/* inside the slot's own struct */
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, NULL) == -EPROTO);
	*p = keep;
	p->bytes += 16;
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, NULL) == -EPROTO);
	*p = keep;
	p->depth = 0;
	p->bytes = 0;
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, NULL) == -EPROTO);
	*p = keep;
	p->offset += 4;
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, NULL) == -EPROTO);
	*p = keep;
	s->views[1].form = 7;
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, NULL) == -EPROTO);
	s->views[1].form = SKY_VIEW_PANORAMA;
	CHECK(skysample_view_from_slot(r->hdr, r->slot, "pano", &t, NULL) == 0);
}

/* The checksum as PROTOCOL.md words it, computed here by hand. */
static void test_checksum(struct region *r)
{
	struct sky_shm_slot *s = (struct sky_shm_slot *)r->slot;
	const struct sky_shm_table *a = &r->hdr->tables[0];
	uint64_t c = sky_shm_checksum_words(SKY_SHM_CHECKSUM_SEED, &s->state, sizeof(s->state) / 8);
	c = sky_shm_checksum_words(c, &s->clouds, sizeof(s->clouds) / 8);
	c = sky_shm_checksum_words(c, r->slot + a->offset, a->bytes / 8);
	c = sky_shm_checksum_words(c, s->views, 4 * sizeof(s->views[0]) / 8);
	c = sky_shm_checksum_words(c, r->slot + r->hdr->view_offset, a->bytes / 8);
	c = sky_shm_checksum_words(c, r->slot + r->arc_offset, s->views[1].panorama.bytes / 8);
	c = sky_shm_checksum_words(c, r->slot + r->arc_offset, s->views[2].panorama.bytes / 8);
	c = sky_shm_checksum_words(c, r->slot + r->ring_offset, s->views[3].panorama.bytes / 8);
	CHECK_EQ(skysample_slot_checksum(r->hdr, s), c);
	CHECK_EQ(s->checksum, c);
	/* A panorama's texel counts; a panorama view's unused volume does not. */
	float *px = (float *)(r->slot + r->arc_offset) + 4 * 37;
	float keep = *px;
	*px += 1.0f;
	CHECK(skysample_slot_checksum(r->hdr, s) != c);
	*px = keep;
	unsigned char *unused = r->slot + r->hdr->view_offset + 2 * r->hdr->view_stride;
	*unused ^= 0xff;
	CHECK_EQ(skysample_slot_checksum(r->hdr, s), c);
	*unused ^= 0xff;
	/* A panorama outside the slot adds nothing: no match, no read. */
	s->views[3].panorama.offset = r->hdr->slot_bytes;
	CHECK(skysample_slot_checksum(r->hdr, s) != c);
	s->views[3].panorama.offset = r->ring_offset;
	CHECK_EQ(skysample_slot_checksum(r->hdr, s), c);
}

static void test_libsky(const struct region *r)
{
	const struct sky_shm_slot *s = (const struct sky_shm_slot *)r->slot;
	struct sky_view v = { .header = r->hdr, .slot = s, .generation = 1,
			      .valid_tables = s->valid_tables, .slot_base = s };
	CHECK(SKY_VERSION_MAJOR == 0 && SKY_VERSION_MINOR == 3 && sky_version() == SKY_VERSION);
	CHECK(sky_view_verify(&v));

	/* By direction, both forms; a panorama by screen position too. */
	const struct sky_shm_view *pv = &s->views[1], *vv = &s->views[0];
	double d[3], rgb[3], tr, rgb2[3], tr2, want[3], want_t;
	dir_at(&pv->panorama, 6.25, 2.5, d);
	double w = skymap_aerial_slice(9.0, PD, s->state.aerial_range_km, 1);
	expected(6.25, 2.5, w, PD, want, &want_t);
	CHECK_EQ(sky_sample_view_aerial_dir(&v, "pano", d, 9.0, rgb, &tr), 0);
	CHECK(close_to(rgb, tr, want, want_t, 1e-9));
	double d3[3] = { 3.0 * d[0], 3.0 * d[1], 3.0 * d[2] };	/* any length */
	CHECK_EQ(sky_sample_view_aerial_dir(&v, "pano", d3, 9.0, rgb2, &tr2), 0);
	CHECK(close_to(rgb2, tr2, want, want_t, 1e-12));
	double su = 0.3, sv = 0.8, sd[3];
	skysample_screen_dir(pv->camera_forward, pv->camera_right, pv->camera_up,
			     tan(0.5 * pv->camera_vfov_rad), pv->camera_aspect, su, sv, sd);
	CHECK_EQ(sky_sample_view_aerial(&v, "pano", su, sv, 9.0, rgb, &tr), 0);
	CHECK_EQ(sky_sample_view_aerial_dir(&v, "pano", sd, 9.0, rgb2, &tr2), 0);
	CHECK(close_to(rgb, tr, rgb2, tr2, 1e-12));
	skysample_screen_dir(vv->camera_forward, vv->camera_right, vv->camera_up,
			     tan(0.5 * vv->camera_vfov_rad), vv->camera_aspect, su, sv, sd);
	CHECK_EQ(sky_sample_view_aerial(&v, "vol", su, sv, 9.0, rgb, &tr), 0);
	CHECK_EQ(sky_sample_view_aerial_dir(&v, "vol", sd, 9.0, rgb2, &tr2), 0);
	CHECK(close_to(rgb, tr, rgb2, tr2, 1e-12));
	double zero[3] = { 0.0, 0.0, 0.0 }, nan3[3] = { NAN, 0.0, 1.0 };
	CHECK_EQ(sky_sample_view_aerial_dir(&v, "pano", zero, 9.0, rgb, &tr), -EINVAL);
	CHECK_EQ(sky_sample_view_aerial_dir(&v, "pano", nan3, 9.0, rgb, &tr), -EINVAL);
	CHECK_EQ(sky_sample_view_aerial_dir(&v, "pano", d, -1.0, rgb, &tr), -EINVAL);
	CHECK_EQ(sky_sample_view_aerial_dir(&v, "nobody", d, 9.0, rgb, &tr), -ENOENT);

	/* The texels for upload. */
	const void *texels;
	size_t bytes;
	CHECK(sky_view_aerial_table(&v, "pano", &texels, &bytes) == 0 &&
	      texels == r->slot + r->arc_offset && bytes == (size_t)PW * PH * PD * 16);
	CHECK(sky_view_aerial_table(&v, "ring", &texels, &bytes) == 0 &&
	      texels == r->slot + r->ring_offset && bytes == (size_t)RW * RH * RD * 16);
	CHECK(sky_view_aerial_table(&v, "vol", &texels, &bytes) == 0 &&
	      texels == r->slot + r->hdr->view_offset && bytes == (size_t)AW * AH * AD * 16);

	/* The uniforms: the panorama's fields, 0 for a volume. */
	struct sky_gpu_state g;
	CHECK_EQ(sky_gpu_state(&v, "pano", &g), 0);
	CHECK(g.panorama[0] == 1.0f && g.panorama[1] == 0.05f && g.panorama[2] == -0.3f &&
	      g.panorama[3] == 0.08f);
	CHECK(g.panorama_grid[0] == -0.01f && g.panorama_grid[1] == PW && g.panorama_grid[2] == PH &&
	      g.panorama_grid[3] == 1.0f);
	CHECK(g.camera_forward[0] == (float)pv->camera_forward[0] && g.aerial[3] == 2.0f);
	CHECK_EQ(sky_gpu_state(&v, "ring", &g), 0);
	CHECK(g.panorama_grid[3] == 2.0f && g.panorama_grid[1] == RW && g.panorama[0] == 5.0f);
	CHECK_EQ(sky_gpu_state(&v, "vol", &g), 0);
	CHECK(g.panorama[0] == 0.0f && g.panorama[1] == 0.0f && g.panorama_grid[1] == 0.0f &&
	      g.panorama_grid[3] == 0.0f);
	CHECK(sky_gpu_state(&v, NULL, &g) == 0 && g.panorama_grid[3] == 0.0f);
}

int main(void)
{
	struct region r;
	build(&r);
	test_entries(&r);
	test_sampling(&r);
	test_checksum(&r);
	test_libsky(&r);
	free(r.hdr);
	return test_report("test_skysample_panorama");
}
