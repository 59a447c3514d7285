/* test_f16_read.c - the readers of scaled float16 tables: the publisher puts
 * each table's scale in the slot's state, and proto/skysample.h, libsky's
 * sky_table_scale() and the EXR and PNG writers (dump/) read values, not
 * the stored halves; float32 tables and A are never scaled. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "dump.h"
#include "pub.h"
#include "sky.h"
#include "skysample.h"
#include "test.h"

#define W 8
#define H 4
#define D 2

/* binary16 of a value exactly representable as a normal half. */
static uint16_t to_half(double x)
{
	int e;
	double m = frexp(x, &e);	/* x = m 2^e, m in [0.5, 1) */
	return (uint16_t)(((e - 1 + 15) << 10) | ((uint16_t)(m * 2048.0) & 0x3ff));
}

/* A texel's stored RGBA: halves of small integers, A below 1. */
static void stored(uint32_t i, double ret[4])
{
	ret[0] = 1 + i % 7;
	ret[1] = 1 + i % 5;
	ret[2] = 1 + i % 3;
	ret[3] = 0.25 * (1 + i % 3);
}

static uint16_t *halves(uint32_t texels)
{
	uint16_t *h = malloc(texels * 8);
	for (uint32_t i = 0; i < texels; i++) {
		double v[4];
		stored(i, v);
		for (int c = 0; c < 4; c++)
			h[4 * i + c] = to_half(v[c]);
	}
	return h;
}

static void set(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0)
		FAIL("%s", err);
}

/* Every table of a float16 region, published with scales; read back
 * through the slot as a client reads it. */
static void test_published(void)
{
	static const char *const small[] = { "storage=f16", "transmittance_width=8",
		"transmittance_height=4", "multiscatter_width=8", "multiscatter_height=4",
		"skyview_width=8", "skyview_height=4", "aerial_width=8", "aerial_height=4",
		"aerial_depth=2" };
	static const int32_t scales[STATE_N_TABLES] = { -15, -19, 3, -7 };
	struct sky_state s;
	struct pub *p;
	state_default(&s);
	for (size_t i = 0; i < sizeof(small) / sizeof(small[0]); i++)
		set(&s, small[i]);
	CHECK_EQ(pub_new(&s, 0, &p), 0);
	if (!p)
		return;
	const void *tables[STATE_N_TABLES];
	for (int t = 0; t < STATE_N_TABLES; t++)
		tables[t] = halves(t == STATE_AERIAL ? W * H * D : W * H);
	pub_publish(p, &s, STATE_ALL_TABLES, tables, NULL, scales, 1);

	const uint8_t *base;
	const struct sky_shm_header *h = pub_header(p);
	const struct sky_shm_slot *slot = pub_current(p, &base);
	CHECK(h->layout_version == SKY_SHM_LAYOUT_VERSION && SKY_SHM_LAYOUT_VERSION >= 4); /* rgb_scale_log2 since 4 */
	CHECK_EQ(skysample_slot_checksum(h, base), slot->checksum);
	for (uint32_t id = 0; id < STATE_N_TABLES; id++) {
		struct skysample_table t = { 0 };
		CHECK_EQ(slot->state.rgb_scale_log2[id], scales[id]);
		CHECK(skysample_table_from_slot(h, base, id, &t) == 0 && t.rgb_scale_log2 == scales[id]);
		/* every texel: RGB times 2^k, exactly; A as stored */
		for (uint32_t i = 0; i < t.width * t.height * t.depth; i++) {
			double v[4], want[4];
			skysample_texel(&t, i % t.width, i / t.width % t.height, i / (t.width * t.height), v);
			stored(i, want);
			for (int c = 0; c < 4; c++)
				if (v[c] != (c < 3 ? ldexp(want[c], scales[id]) : want[c]))
					FAIL("table %u texel %u channel %d: %.17g", id, i, c, v[c]);
		}
		/* libsky's factor for clients that upload the texels */
		struct sky_view v = { .header = h, .slot = slot, .valid_tables = slot->valid_tables,
				      .slot_base = base };
		double f = 0;
		CHECK(sky_table_scale(&v, id, &f) == 0 && f == ldexp(1.0, scales[id]));
		v.valid_tables = 0;
		CHECK_EQ(sky_table_scale(&v, id, &f), -ENODATA);
	}
	struct sky_view v = { .header = h, .slot = slot, .valid_tables = 0xf, .slot_base = base };
	double f;
	CHECK(sky_table_scale(&v, SKY_SHM_MAX_TABLES, &f) == -EINVAL && sky_table_scale(&v, 0, NULL) == -EINVAL);
	/* The scale is part of the checksummed state: a reader that copied
	 * a slot with another scale would see the copy fail. */
	struct sky_shm_slot *copy = malloc(h->slot_bytes);
	memcpy(copy, slot, h->slot_bytes);
	copy->state.rgb_scale_log2[SKY_TABLE_SKYVIEW]++;
	CHECK(skysample_slot_checksum(h, copy) != slot->checksum);
	free(copy);
	/* NULL scales: 0 for every table */
	pub_publish(p, &s, STATE_ALL_TABLES, tables, NULL, NULL, 2);
	slot = pub_current(p, &base);
	for (uint32_t id = 0; id < SKY_SHM_MAX_TABLES; id++)
		CHECK_EQ(slot->state.rgb_scale_log2[id], 0);
	for (int t = 0; t < STATE_N_TABLES; t++)
		free((void *)tables[t]);
	pub_free(p);
}

/* A float32 table ignores the field: it is stored as it is. */
static void test_float32_unscaled(void)
{
	float f[4] = { 3.0f, 5.0f, 7.0f, 0.5f };
	struct skysample_table t = { .texels = f, .format = SKY_FORMAT_RGBA32F, .width = 1,
				     .height = 1, .depth = 1, .rgb_scale_log2 = 9 };
	double v[4];
	skysample_texel(&t, 0, 0, 0, v);
	CHECK(v[0] == 3.0 && v[1] == 5.0 && v[2] == 7.0 && v[3] == 0.5);
}

/* The EXR holds values: a scaled float16 table reads back as the float32
 * table of the same values, and previews the same. */
static void test_dump(void)
{
	char dir[] = "/tmp/test_f16_read.XXXXXX", path[128], err[256];
	uint16_t *h = halves(W * H);
	float *f = malloc(W * H * 16);
	for (uint32_t i = 0; i < W * H; i++) {
		double v[4];
		stored(i, v);
		for (int c = 0; c < 4; c++)
			f[4 * i + c] = (float)(c < 3 ? ldexp(v[c], 17) : v[c]);	/* above 65504 */
	}
	CHECK(mkdtemp(dir) != NULL);
	struct dump_table th = { .name = "skyview", .width = W, .height = H, .depth = 1,
				 .format = SKY_FORMAT_RGBA16F, .texels = h, .rgb_scale_log2 = 17 };
	struct dump_table tf = th;
	tf.format = SKY_FORMAT_RGBA32F;
	tf.texels = f;
	tf.rgb_scale_log2 = 0;
	snprintf(path, sizeof(path), "%s/f16.exr", dir);
	CHECK_EQ(dump_exr(path, &th, err, sizeof(err)), 0);
	struct dump_exr_info info;
	float *back = NULL;
	CHECK_EQ(dump_read_exr(path, &info, &back, err, sizeof(err)), 0);
	if (back) {
		/* the file's scanlines in table order: compare as sets of values
		 * through the float32 table written the same way */
		float *ref = NULL;
		char ref_path[160];
		snprintf(ref_path, sizeof(ref_path), "%s/f32.exr", dir);
		CHECK_EQ(dump_exr(ref_path, &tf, err, sizeof(err)), 0);
		CHECK_EQ(dump_read_exr(ref_path, &info, &ref, err, sizeof(err)), 0);
		CHECK(ref && memcmp(back, ref, W * H * 16) == 0);
		CHECK(back[0] == 131072.0f && back[3] == 0.25f);	/* texel 0: 1 * 2^17, A 0.25 */
		unlink(ref_path);
		free(ref);
	}
	double eh, ef;
	CHECK(dump_auto_exposure(&th, &eh) == 0 && dump_auto_exposure(&tf, &ef) == 0 && eh == ef);
	unlink(path);
	rmdir(dir);
	free(back);
	free(h);
	free(f);
}

int main(void)
{
	test_published();
	test_float32_unscaled();
	test_dump();
	return test_report("test_f16_read");
}
