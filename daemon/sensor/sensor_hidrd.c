/* sensor_hidrd.c - a HID report descriptor parser that finds an ambient
 * light sensor's fields, and bit-level access to them in reports. Pure:
 * what a device sends is untrusted, so every length is checked. */
#include "sensor_internal.h"

#include <errno.h>
#include <math.h>
#include <string.h>

#define MAX_USAGES 256
#define MAX_DEPTH 16
#define MAX_PUSH 8
#define MAX_REPORT_BITS (4096u * 8u)

struct hid_global {
	uint16_t page;
	int64_t lmin;
	int64_t lmax_signed;
	int64_t lmax_unsigned;
	uint32_t unit;
	int unit_exp;
	uint32_t size;
	uint8_t id;
	uint32_t count;
};

struct hid_collection {
	uint32_t usage;
	int in_als;			/* inside the first Ambient Light collection */
};

struct hid_parser {
	struct hid_global g;
	struct hid_global stack[MAX_PUSH];
	int n_stack;
	/* Local usages: short ones take the usage page in force at the main
	 * item (HID 1.11, 6.2.2.8), so they are resolved there. */
	uint32_t usages[MAX_USAGES];
	uint8_t usage_short[MAX_USAGES];
	int n_usages;
	uint32_t usage_min, usage_max;
	int usage_min_short, have_min, have_max;
	struct hid_collection coll[MAX_DEPTH];
	int depth;
	int als_done;			/* the first ALS collection was closed */
	struct sensor_hid_layout *out;
};

static int64_t sign_extend(uint32_t v, int bytes)
{
	switch (bytes) {
	case 1:
		return (int8_t)v;
	case 2:
		return (int16_t)v;
	default:
		return (int32_t)v;
	}
}

static uint32_t resolve(const struct hid_parser *p, uint32_t usage, int is_short)
{
	return is_short ? ((uint32_t)p->g.page << 16) | (usage & 0xffff) : usage;
}

static void add_usage(struct hid_parser *p, uint32_t usage, int is_short)
{
	if (p->n_usages >= MAX_USAGES)
		return;
	p->usages[p->n_usages] = usage;
	p->usage_short[p->n_usages] = (uint8_t)is_short;
	p->n_usages++;
}

/* A usage range becomes a list (capped: a sensor has no use for more). */
static void flush_range(struct hid_parser *p)
{
	if (!(p->have_min && p->have_max))
		return;
	for (uint32_t u = p->usage_min; u <= p->usage_max && p->n_usages < MAX_USAGES; u++) {
		add_usage(p, u, p->usage_min_short);
		if (u == UINT32_MAX)
			break;
	}
	p->have_min = p->have_max = 0;
}

static void clear_locals(struct hid_parser *p)
{
	p->n_usages = 0;
	p->have_min = p->have_max = 0;
}

static int report_index(struct sensor_hid_layout *l, enum sensor_hid_kind kind, uint8_t id)
{
	for (size_t i = 0; i < l->n_reports; i++)
		if (l->reports[i].kind == kind && l->reports[i].id == id)
			return (int)i;
	if (l->n_reports >= SENSOR_HID_MAX_REPORTS)
		return -1;
	l->reports[l->n_reports].kind = kind;
	l->reports[l->n_reports].id = id;
	l->reports[l->n_reports].bytes = 0;	/* bits while parsing */
	return (int)l->n_reports++;
}

/* The value a selector property is set to: the place of want among an
 * array's selectors, else the second value of the range. */
static int64_t wanted_value(const struct hid_parser *p, const struct sensor_hid_field *f,
			    uint32_t want)
{
	if (f->is_array)
		for (int i = 0; i < p->n_usages; i++)
			if (resolve(p, p->usages[i], p->usage_short[i]) == want)
				return f->logical_min + i;
	return f->logical_min + 1;
}

/* Files a field of the first ALS collection where it belongs. */
static void consider(struct hid_parser *p, struct sensor_hid_field *f)
{
	struct sensor_hid_layout *l = p->out;
	uint32_t u = f->usage;
	struct sensor_hid_field *slot = NULL;
	uint32_t want = 0;

	if (f->kind == SENSOR_HID_INPUT) {
		if (u == SENSOR_HID_ILLUMINANCE && !f->is_array)
			slot = &l->illuminance;
		else if (u == SENSOR_HID_SENSOR_STATE)
			slot = &l->sensor_state, want = SENSOR_HID_STATE_READY;
	} else if (f->kind == SENSOR_HID_FEATURE) {
		if (u == SENSOR_HID_REPORTING_STATE)
			slot = &l->reporting_state, want = SENSOR_HID_REPORTING_ALL_EVENTS;
		else if (u == SENSOR_HID_POWER_STATE)
			slot = &l->power_state, want = SENSOR_HID_POWER_D0;
		else if (u == SENSOR_HID_REPORT_INTERVAL && !f->is_array)
			slot = &l->report_interval;
		else if ((u == SENSOR_HID_SENSITIVITY_ABS ||
			  u == (SENSOR_HID_ILLUMINANCE | SENSOR_HID_MOD_SENSITIVITY_ABS)) && !f->is_array)
			slot = &l->sensitivity_abs;
		else if ((u == SENSOR_HID_SENSITIVITY_REL_PCT ||
			  u == (SENSOR_HID_ILLUMINANCE | SENSOR_HID_MOD_SENSITIVITY_REL_PCT)) &&
			 !f->is_array)
			slot = &l->sensitivity_rel;
	}
	if (!slot || slot->present)
		return;
	if (want)
		f->wanted = wanted_value(p, f, want);
	*slot = *f;
	slot->present = 1;
}

/* An Input, Output or Feature item: report_count fields of report_size
 * bits each, appended to their report. */
static int main_item(struct hid_parser *p, enum sensor_hid_kind kind, uint32_t flags)
{
	struct sensor_hid_layout *l = p->out;
	int constant = flags & 1, variable = flags & 2;
	int r;

	flush_range(p);
	if (p->g.id)
		l->uses_report_ids = 1;
	r = report_index(l, kind, p->g.id);
	if (r < 0)
		return -EINVAL;
	uint64_t bits = (uint64_t)p->g.size * p->g.count;
	if (l->reports[r].bytes + bits > MAX_REPORT_BITS)
		return -EINVAL;
	uint32_t start = l->reports[r].bytes;
	l->reports[r].bytes += (uint32_t)bits;
	int inside = p->depth > 0 && p->coll[p->depth - 1].in_als;
	if (constant || !inside || p->g.size == 0 || p->g.size > 32)
		return 0;

	struct sensor_hid_field f;
	memset(&f, 0, sizeof(f));
	f.kind = kind;
	f.report_id = p->g.id;
	f.bit_size = p->g.size;
	f.is_array = !variable;
	f.logical_min = p->g.lmin;
	f.logical_max = p->g.lmin >= 0 ? p->g.lmax_unsigned : p->g.lmax_signed;
	f.unit = p->g.unit;
	f.unit_exponent = p->g.unit_exp;
	if (!variable) {
		/* An array names its selectors; what it is comes from its
		 * (logical) collection. */
		f.bit_offset = start;
		f.usage = p->coll[p->depth - 1].usage;
		consider(p, &f);
		return 0;
	}
	for (uint32_t i = 0; i < p->g.count && p->n_usages; i++) {
		int k = i < (uint32_t)p->n_usages ? (int)i : p->n_usages - 1;
		f.bit_offset = start + i * p->g.size;
		f.usage = resolve(p, p->usages[k], p->usage_short[k]);
		consider(p, &f);
	}
	return 0;
}

static int collection(struct hid_parser *p)
{
	flush_range(p);
	if (p->depth >= MAX_DEPTH)
		return -EINVAL;
	uint32_t usage = p->n_usages ? resolve(p, p->usages[0], p->usage_short[0]) : 0;
	int parent_in = p->depth > 0 && p->coll[p->depth - 1].in_als;
	p->coll[p->depth].usage = usage;
	p->coll[p->depth].in_als = parent_in || (usage == SENSOR_HID_ALS && !p->als_done);
	p->depth++;
	return 0;
}

static int end_collection(struct hid_parser *p)
{
	if (p->depth <= 0)
		return -EINVAL;
	p->depth--;
	if (p->coll[p->depth].in_als && !(p->depth > 0 && p->coll[p->depth - 1].in_als))
		p->als_done = 1;
	return 0;
}

static int global_item(struct hid_parser *p, int tag, uint32_t v, int bytes)
{
	switch (tag) {
	case 0x0: p->g.page = (uint16_t)v; break;
	case 0x1: p->g.lmin = sign_extend(v, bytes); break;
	case 0x2:
		p->g.lmax_signed = sign_extend(v, bytes);
		p->g.lmax_unsigned = v;
		break;
	case 0x5: p->g.unit_exp = (v & 0x8) ? (int)(v & 0xf) - 16 : (int)(v & 0x7); break;
	case 0x6: p->g.unit = v; break;
	case 0x7: p->g.size = v; break;
	case 0x8:
		if (v == 0 || v > 255)
			return -EINVAL;
		p->g.id = (uint8_t)v;
		break;
	case 0x9: p->g.count = v; break;
	case 0xA:
		if (p->n_stack >= MAX_PUSH)
			return -EINVAL;
		p->stack[p->n_stack++] = p->g;
		break;
	case 0xB:
		if (p->n_stack <= 0)
			return -EINVAL;
		p->g = p->stack[--p->n_stack];
		break;
	default: break;			/* physical range, reserved */
	}
	return 0;
}

static void local_item(struct hid_parser *p, int tag, uint32_t v, int bytes)
{
	int is_short = bytes <= 2;

	switch (tag) {
	case 0x0: add_usage(p, v, is_short); break;
	case 0x1:
		p->usage_min = v;
		p->usage_min_short = is_short;
		p->have_min = 1;
		break;
	case 0x2:
		p->usage_max = is_short && p->have_min && !p->usage_min_short ?
				       (p->usage_min & 0xffff0000u) | v : v;
		p->have_max = 1;
		break;
	default: break;			/* designators, strings, delimiters */
	}
	if (p->have_min && p->have_max)
		flush_range(p);
}

static int item(struct hid_parser *p, int type, int tag, uint32_t v, int bytes)
{
	int r = 0;

	if (type == 0) {
		switch (tag) {
		case 0x8: r = main_item(p, SENSOR_HID_INPUT, v); break;
		case 0x9: r = main_item(p, SENSOR_HID_OUTPUT, v); break;
		case 0xB: r = main_item(p, SENSOR_HID_FEATURE, v); break;
		case 0xA: r = collection(p); break;
		case 0xC: r = end_collection(p); break;
		default: break;
		}
		clear_locals(p);
		return r;
	}
	if (type == 1)
		return global_item(p, tag, v, bytes);
	if (type == 2)
		local_item(p, tag, v, bytes);
	return 0;
}

int sensor_hid_parse(const uint8_t *desc, size_t len, struct sensor_hid_layout *ret)
{
	static const int sizes[4] = { 0, 1, 2, 4 };
	struct hid_parser p;
	size_t i = 0;

	memset(&p, 0, sizeof(p));
	memset(ret, 0, sizeof(*ret));
	p.out = ret;
	while (i < len) {
		uint8_t b = desc[i];
		if (b == 0xFE) {	/* long item: size, tag, data */
			if (i + 2 >= len || i + 3 + desc[i + 1] > len)
				return -EINVAL;
			i += 3 + desc[i + 1];
			continue;
		}
		int bytes = sizes[b & 3];
		if (i + 1 + bytes > len)
			return -EINVAL;
		uint32_t v = 0;
		for (int k = 0; k < bytes; k++)
			v |= (uint32_t)desc[i + 1 + k] << (8 * k);
		int r = item(&p, (b >> 2) & 3, b >> 4, v, bytes);
		if (r < 0)
			return r;
		i += 1 + bytes;
	}
	if (p.depth != 0)
		return -EINVAL;
	for (size_t k = 0; k < ret->n_reports; k++)
		ret->reports[k].bytes = (ret->reports[k].bytes + 7) / 8 + (ret->uses_report_ids ? 1 : 0);
	return ret->illuminance.present ? 0 : -ENOENT;
}

uint32_t sensor_hid_report_bytes(const struct sensor_hid_layout *l, enum sensor_hid_kind kind,
				 uint8_t id)
{
	for (size_t i = 0; i < l->n_reports; i++)
		if (l->reports[i].kind == kind && l->reports[i].id == id)
			return l->reports[i].bytes;
	return 0;
}

/* Where f's bits start in a report buffer, or -EMSGSIZE. With report
 * ids, the buffer's first byte is the id: checked when reading, written
 * when building. */
static int locate(const struct sensor_hid_layout *l, const struct sensor_hid_field *f,
		  uint8_t *build, const uint8_t *report, size_t len, size_t *ret_bit)
{
	size_t head = 0;

	if (l->uses_report_ids) {
		if (len < 1)
			return -EMSGSIZE;
		if (build)
			build[0] = f->report_id;
		else if (report[0] != f->report_id)
			return -EMSGSIZE;
		head = 8;
	}
	size_t bit = head + f->bit_offset;
	if (f->bit_size == 0 || f->bit_size > 32 || bit + f->bit_size > (size_t)len * 8)
		return -EMSGSIZE;
	*ret_bit = bit;
	return 0;
}

int sensor_hid_get(const struct sensor_hid_layout *l, const struct sensor_hid_field *f,
		   const uint8_t *report, size_t len, int64_t *ret_value)
{
	size_t bit;
	uint64_t v = 0;

	if (locate(l, f, NULL, report, len, &bit) < 0)
		return -EMSGSIZE;
	for (uint32_t k = 0; k < f->bit_size; k++, bit++)
		v |= (uint64_t)((report[bit / 8] >> (bit % 8)) & 1) << k;
	if (f->logical_min < 0 && f->bit_size < 64 && (v >> (f->bit_size - 1)) & 1)
		v |= ~(uint64_t)0 << f->bit_size;
	*ret_value = (int64_t)v;
	return 0;
}

int sensor_hid_put(const struct sensor_hid_layout *l, const struct sensor_hid_field *f,
		   uint8_t *report, size_t len, int64_t value)
{
	size_t bit;
	uint64_t v = (uint64_t)value;

	if (locate(l, f, report, report, len, &bit) < 0)
		return -EMSGSIZE;
	for (uint32_t k = 0; k < f->bit_size; k++, bit++) {
		uint8_t mask = (uint8_t)(1u << (bit % 8));
		if ((v >> k) & 1)
			report[bit / 8] |= mask;
		else
			report[bit / 8] &= (uint8_t)~mask;
	}
	return 0;
}

int sensor_hid_lux_scale(const struct sensor_hid_field *f, double *ret_scale)
{
	if (f->unit != SENSOR_HID_UNIT_LUX && f->unit != 0 && f->unit != 1)
		return -ENOTSUP;
	*ret_scale = pow(10.0, f->unit_exponent);
	return 0;
}

enum sensor_hid_input sensor_hid_input(const struct sensor_hid_layout *l, const uint8_t *report,
				       size_t len, int64_t *ret_value)
{
	const struct sensor_hid_field *f = &l->illuminance, *st = &l->sensor_state;
	int64_t v, state;

	if (l->uses_report_ids && len >= 1 && report[0] != f->report_id &&
	    sensor_hid_report_bytes(l, SENSOR_HID_INPUT, report[0]))
		return SENSOR_HID_IN_OTHER;
	if (sensor_hid_get(l, f, report, len, &v) < 0)
		return SENSOR_HID_IN_MALFORMED;
	*ret_value = v;
	if (v < f->logical_min || v > f->logical_max)
		return SENSOR_HID_IN_RANGE;
	if (st->present && st->report_id == f->report_id &&
	    sensor_hid_get(l, st, report, len, &state) == 0 && state != st->wanted)
		return SENSOR_HID_IN_NOT_READY;
	return SENSOR_HID_IN_READING;
}
