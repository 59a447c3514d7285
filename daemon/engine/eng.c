/* eng.c - the LUT engine's small public accessors; the engine itself is
 * eng_device.c (device and buffers), eng_params.c (what a state uploads)
 * and eng_run.c (the passes). */
#include "eng_internal.h"

#include <math.h>
#include <string.h>

const struct eng_device *eng_device(const struct eng *e)
{
	return &e->info;
}

uint64_t eng_max_table_bytes(const struct eng *e)
{
	return e->limits.maxStorageBufferRange;
}

/* The value of a binary16 bit pattern (finite), times 2^k. */
static double half_value(uint16_t h, int32_t k)
{
	int exponent = (h >> 10) & 0x1f, mantissa = h & 0x3ff;
	double v = exponent ? ldexp(mantissa + 1024, exponent - 25) : ldexp(mantissa, -24);
	return ldexp(h & 0x8000 ? -v : v, k);
}

void eng_f16_range(const struct eng *e, const struct sky_state *s, uint32_t mask,
		   struct eng_f16_range *ret)
{
	double floor_cd_m2, gain;

	memset(ret, 0, sizeof(*ret));
	if (s->quality.storage != STATE_F16)
		return;
	state_night_floor(s, &floor_cd_m2, &gain);
	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t bytes;
		const uint16_t *h = eng_table(e, (enum state_table)t, &bytes);
		int32_t k = e->rgb_scale_log2[t];
		if (!(mask & STATE_BIT(t)) || !h)
			continue;
		for (size_t i = 0; i < bytes / 8; i++) {
			for (int c = 0; c < 3; c++) {
				uint16_t x = h[4 * i + c], exponent = (x >> 10) & 0x1f;
				if (exponent == 0x1f)
					ret->overflow++;
				else if (exponent == 0 && (x & 0x3ff) && t >= STATE_SKYVIEW &&
					 fabs(half_value(x, k)) >= floor_cd_m2)
					ret->subnormal++;
			}
		}
		if (t >= STATE_SKYVIEW)
			ret->radiance_values += 3 * (bytes / 8);
	}
}

int eng_f16_broken(const struct eng_f16_range *r)
{
	return r->overflow > 0 || r->subnormal * 100 > r->radiance_values;
}

uint64_t eng_pipelines_created(const struct eng *e)
{
	return e->pipelines_created;
}

int eng_pipelines_ordered(const struct eng *e)
{
	return e->compiling ? e->deferred.orders : 0;
}

int eng_event_fd(const struct eng *e)
{
	return e->event_fd;
}

void eng_forget_columns(struct eng *e)
{
	e->columns_valid = false;
}

const void *eng_table(const struct eng *e, enum state_table t, size_t *ret_bytes)
{
	if (ret_bytes)
		*ret_bytes = e->table_bytes[t];
	return e->direct[t] ? (const uint8_t *)e->table[t].map + e->published_offset[t] : e->readback[t].map;
}

const void *eng_panoramas(const struct eng *e, size_t *ret_bytes)
{
	const struct gpu_buffer *t = &e->table[STATE_AERIAL];
	size_t published = (size_t)aplan_published_bytes(&e->aplan);
	if (ret_bytes)
		*ret_bytes = published;
	if (!published)
		return NULL;
	return e->direct[STATE_AERIAL] ? (const uint8_t *)t->map + e->panorama_offset
				       : (const uint8_t *)e->readback[STATE_AERIAL].map + e->table_bytes[STATE_AERIAL];
}

int32_t eng_table_scale_log2(const struct eng *e, enum state_table t)
{
	return e->rgb_scale_log2[t];
}
