/* test_sensor_hid.c - the HID report descriptor parser of the sensor
 * module: an ambient light sensor found by its usages, alone or in a
 * sensor hub; field offsets, sizes, ranges, units and selector values;
 * refusals of malformed descriptors; bit access to reports; and random
 * mutations of a descriptor, which must never read out of bounds. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sensor_internal.h"
#include "test.h"

#define U16(x) (x) & 0xff, (x) >> 8
/* Usage (16-bit id), Usage Page, Logical Min/Max, Report Size/Count/ID */
#define USAGE(x) 0x0A, U16(x)
#define PAGE(x) 0x05, (x)
#define LMIN8(x) 0x15, (x)
#define LMAX8(x) 0x25, (x)
#define LMAX16(x) 0x26, U16(x)
#define LMAX32(a, b, c, d) 0x27, (a), (b), (c), (d)
#define SIZE(x) 0x75, (x)
#define COUNT(x) 0x95, (x)
#define ID(x) 0x85, (x)
#define EXP(x) 0x55, (x)
#define COLL(x) 0xA1, (x)
#define END 0xC0
#define INPUT(x) 0x81, (x)
#define FEATURE(x) 0xB1, (x)

/* An ambient light sensor as the HID Sensor Usages document draws one:
 * report 1, features (reporting state and power state as named arrays,
 * report interval, illuminance change sensitivity), inputs (sensor state,
 * illuminance in lux with exponent -2). */
static const uint8_t als_desc[] = {
	PAGE(0x20), 0x09, 0x41, COLL(0x01), ID(1),
	USAGE(0x0316), LMIN8(0), LMAX8(5), SIZE(8), COUNT(1), COLL(0x02),
	USAGE(0x0840), USAGE(0x0841), USAGE(0x0842), USAGE(0x0843), USAGE(0x0844), USAGE(0x0845),
	FEATURE(0x00), END,
	USAGE(0x0319), LMIN8(0), LMAX8(5), SIZE(8), COUNT(1), COLL(0x02),
	USAGE(0x0850), USAGE(0x0851), USAGE(0x0852), USAGE(0x0853), USAGE(0x0854), USAGE(0x0855),
	FEATURE(0x00), END,
	USAGE(0x030E), LMIN8(0), LMAX32(0xff, 0xff, 0xff, 0xff), SIZE(32), COUNT(1), EXP(0),
	FEATURE(0x02),
	USAGE(0x14D1), LMIN8(0), LMAX16(0xffff), SIZE(16), COUNT(1), EXP(0x0E), FEATURE(0x02),
	USAGE(0x0201), LMIN8(0), LMAX8(6), SIZE(8), COUNT(1), COLL(0x02),
	USAGE(0x0800), USAGE(0x0801), USAGE(0x0802), USAGE(0x0803), USAGE(0x0804), USAGE(0x0805),
	USAGE(0x0806), INPUT(0x00), END,
	USAGE(0x04D1), LMIN8(0), LMAX32(0xff, 0xff, 0xff, 0xff), SIZE(32), COUNT(1),
	0x67, 0xE1, 0x00, 0x00, 0x01, EXP(0x0E), INPUT(0x02),
	END,
};

static void test_flat(void)
{
	struct sensor_hid_layout l;
	double scale;

	CHECK_EQ(sensor_hid_parse(als_desc, sizeof(als_desc), &l), 0);
	CHECK(l.uses_report_ids);
	CHECK(l.illuminance.present && l.illuminance.report_id == 1);
	CHECK(l.illuminance.bit_offset == 8 && l.illuminance.bit_size == 32);
	CHECK(l.illuminance.logical_min == 0 && l.illuminance.logical_max == 0xffffffffll);
	CHECK(l.illuminance.unit == SENSOR_HID_UNIT_LUX && l.illuminance.unit_exponent == -2);
	CHECK(sensor_hid_lux_scale(&l.illuminance, &scale) == 0 && fabs(scale - 0.01) < 1e-15);
	CHECK(l.sensor_state.present && l.sensor_state.is_array && l.sensor_state.bit_offset == 0);
	CHECK_EQ(l.sensor_state.wanted, 1);
	CHECK(l.reporting_state.present && l.reporting_state.is_array);
	CHECK(l.reporting_state.bit_offset == 0 && l.reporting_state.wanted == 1);
	CHECK(l.power_state.present && l.power_state.bit_offset == 8 && l.power_state.wanted == 1);
	CHECK(l.report_interval.present && l.report_interval.bit_offset == 16);
	CHECK(l.report_interval.bit_size == 32 && l.report_interval.unit == 0);
	CHECK(l.sensitivity_abs.present && l.sensitivity_abs.bit_offset == 48);
	CHECK(l.sensitivity_abs.unit_exponent == -2 && !l.sensitivity_rel.present);
	CHECK_EQ(sensor_hid_report_bytes(&l, SENSOR_HID_FEATURE, 1), 9);
	CHECK_EQ(sensor_hid_report_bytes(&l, SENSOR_HID_INPUT, 1), 6);
	CHECK_EQ(sensor_hid_report_bytes(&l, SENSOR_HID_INPUT, 2), 0);

	/* An input report: id 1, state Ready (1), 123456 = 1234.56 lx. */
	const uint8_t in[] = { 1, 1, 0x40, 0xE2, 0x01, 0x00 };
	int64_t v;
	CHECK(sensor_hid_get(&l, &l.illuminance, in, sizeof(in), &v) == 0 && v == 123456);
	CHECK(sensor_hid_get(&l, &l.sensor_state, in, sizeof(in), &v) == 0 && v == 1);
	CHECK_EQ(sensor_hid_get(&l, &l.illuminance, in, sizeof(in) - 1, &v), -EMSGSIZE);
	const uint8_t other[] = { 2, 1, 0x40, 0xE2, 0x01, 0x00 };
	CHECK_EQ(sensor_hid_get(&l, &l.illuminance, other, sizeof(other), &v), -EMSGSIZE);
	CHECK_EQ(sensor_hid_get(&l, &l.illuminance, in, 0, &v), -EMSGSIZE);

	/* A feature report built field by field. */
	uint8_t feat[9];
	memset(feat, 0xAA, sizeof(feat));
	CHECK_EQ(sensor_hid_put(&l, &l.reporting_state, feat, sizeof(feat), 1), 0);
	CHECK_EQ(sensor_hid_put(&l, &l.report_interval, feat, sizeof(feat), 500), 0);
	CHECK_EQ(sensor_hid_put(&l, &l.sensitivity_abs, feat, sizeof(feat), 0), 0);
	const uint8_t want[] = { 1, 1, 0xAA, 0xF4, 0x01, 0, 0, 0, 0 };
	CHECK(memcmp(feat, want, sizeof(want)) == 0);
	CHECK_EQ(sensor_hid_put(&l, &l.sensitivity_abs, feat, 8, 0), -EMSGSIZE);
}

/* A hub: an accelerometer (report 2) and an ambient light sensor (report
 * 3, no report-level properties but a relative sensitivity, signed 16-bit
 * illuminance, unit not given, a selector list starting at 1). */
static const uint8_t hub_desc[] = {
	PAGE(0x20), 0x09, 0x01, COLL(0x01),
	0x09, 0x73, COLL(0x00), ID(2),
	USAGE(0x0453), USAGE(0x0454), USAGE(0x0455), 0x16, U16(0x8001), LMAX16(0x7fff), SIZE(16),
	COUNT(3), INPUT(0x02), END,
	0x09, 0x41, COLL(0x00), ID(3),
	USAGE(0x0316), LMIN8(1), LMAX8(6), SIZE(8), COUNT(1), COLL(0x02),
	USAGE(0x0840), USAGE(0x0841), USAGE(0x0842), USAGE(0x0843), USAGE(0x0844), USAGE(0x0845),
	FEATURE(0x00), END,
	USAGE(0xE4D1), LMIN8(0), LMAX16(10000), SIZE(16), COUNT(1), EXP(0x0E), FEATURE(0x02),
	SIZE(4), COUNT(1), FEATURE(0x03),	/* padding */
	USAGE(0x04D1), 0x16, U16(0x8000), LMAX16(0x7fff), SIZE(16), COUNT(1), EXP(0x01),
	0x65, 0x00, INPUT(0x02),
	END,
	END,
};

static void test_hub(void)
{
	struct sensor_hid_layout l;
	double scale;
	int64_t v;

	CHECK_EQ(sensor_hid_parse(hub_desc, sizeof(hub_desc), &l), 0);
	CHECK(l.illuminance.report_id == 3 && l.illuminance.bit_offset == 0);
	CHECK(l.illuminance.logical_min == -32768 && l.illuminance.logical_max == 32767);
	CHECK(sensor_hid_lux_scale(&l.illuminance, &scale) == 0 && scale == 10.0);
	CHECK(l.reporting_state.present && l.reporting_state.wanted == 2);
	CHECK(l.sensitivity_rel.present && l.sensitivity_rel.bit_offset == 8);
	CHECK(!l.sensitivity_abs.present && !l.power_state.present && !l.sensor_state.present);
	CHECK_EQ(sensor_hid_report_bytes(&l, SENSOR_HID_INPUT, 2), 7);
	CHECK_EQ(sensor_hid_report_bytes(&l, SENSOR_HID_INPUT, 3), 3);
	CHECK_EQ(sensor_hid_report_bytes(&l, SENSOR_HID_FEATURE, 3), 5);	/* 8 + 16 + 4 bits */
	const uint8_t in[] = { 3, 0xFE, 0xFF };
	CHECK(sensor_hid_get(&l, &l.illuminance, in, sizeof(in), &v) == 0 && v == -2);
}

/* A keyboard: no sensor at all. */
static const uint8_t keyboard_desc[] = {
	0x05, 0x01, 0x09, 0x06, 0xA1, 0x01, 0x05, 0x07, 0x19, 0xE0, 0x29, 0xE7, 0x15, 0x00,
	0x25, 0x01, 0x75, 0x01, 0x95, 0x08, 0x81, 0x02, 0x95, 0x01, 0x75, 0x08, 0x81, 0x01,
	0x95, 0x06, 0x75, 0x08, 0x15, 0x00, 0x25, 0x65, 0x05, 0x07, 0x19, 0x00, 0x29, 0x65,
	0x81, 0x00, 0xC0,
};

static void test_refusals(void)
{
	struct sensor_hid_layout l;
	uint8_t buf[sizeof(als_desc) + 8];
	double scale;

	CHECK_EQ(sensor_hid_parse(keyboard_desc, sizeof(keyboard_desc), &l), -ENOENT);
	CHECK(sensor_hid_parse(NULL, 0, &l) == -ENOENT);
	/* Cut in the middle of an item; a collection left open. */
	CHECK_EQ(sensor_hid_parse(als_desc, 7, &l), -EINVAL);
	CHECK_EQ(sensor_hid_parse(als_desc, sizeof(als_desc) - 1, &l), -EINVAL);
	/* An End Collection too many. */
	memcpy(buf, als_desc, sizeof(als_desc));
	buf[sizeof(als_desc)] = END;
	CHECK_EQ(sensor_hid_parse(buf, sizeof(als_desc) + 1, &l), -EINVAL);
	/* Report id 0 is reserved; Pop without Push; a report of 8 KiB. */
	const uint8_t id0[] = { PAGE(0x20), ID(0) };
	CHECK_EQ(sensor_hid_parse(id0, sizeof(id0), &l), -EINVAL);
	const uint8_t pop[] = { 0xB4 };
	CHECK_EQ(sensor_hid_parse(pop, sizeof(pop), &l), -EINVAL);
	const uint8_t big[] = { SIZE(32), 0x96, U16(2048), INPUT(0x01) };
	CHECK_EQ(sensor_hid_parse(big, sizeof(big), &l), -EINVAL);
	/* A long item is skipped; one running past the end is not. */
	uint8_t lng[sizeof(als_desc) + 5] = { 0xFE, 2, 0x10, 0xAB, 0xCD };
	memcpy(lng + 5, als_desc, sizeof(als_desc));
	CHECK_EQ(sensor_hid_parse(lng, sizeof(lng), &l), 0);
	CHECK_EQ(sensor_hid_parse(lng, 4, &l), -EINVAL);

	/* A unit skyd cannot turn into lux: kelvin. */
	memcpy(buf, als_desc, sizeof(als_desc));
	uint8_t *u = memchr(buf, 0x67, sizeof(als_desc));
	CHECK(u && u[1] == 0xE1);
	u[1] = 0x01, u[2] = 0x00, u[3] = 0x01, u[4] = 0x00;	/* 0x00010001 */
	CHECK_EQ(sensor_hid_parse(buf, sizeof(als_desc), &l), 0);
	CHECK_EQ(sensor_hid_lux_scale(&l.illuminance, &scale), -ENOTSUP);
}

/* Bits that straddle bytes, and the sign of a field whose range is
 * negative. */
static void test_bits(void)
{
	struct sensor_hid_layout l;
	struct sensor_hid_field f;
	uint8_t r[4] = { 0 };
	int64_t v;

	memset(&l, 0, sizeof(l));
	memset(&f, 0, sizeof(f));
	f.bit_offset = 3;
	f.bit_size = 12;
	f.logical_min = 0;
	CHECK_EQ(sensor_hid_put(&l, &f, r, sizeof(r), 0xABC), 0);
	CHECK(r[0] == 0xE0 && r[1] == 0x55 && r[2] == 0x00);
	CHECK(sensor_hid_get(&l, &f, r, sizeof(r), &v) == 0 && v == 0xABC);
	f.logical_min = -2048;
	CHECK(sensor_hid_get(&l, &f, r, sizeof(r), &v) == 0 && v == 0xABC - 4096);
	f.bit_offset = 21;
	CHECK_EQ(sensor_hid_get(&l, &f, r, sizeof(r), &v), -EMSGSIZE);
	f.bit_offset = 20;
	CHECK_EQ(sensor_hid_get(&l, &f, r, sizeof(r), &v), 0);
}

/* Mutated descriptors parse or are refused; whatever parses is read from
 * reports of every length without reading past them (ASan builds check). */
static void test_mutations(void)
{
	uint64_t x = 88172645463325252ull;
	uint8_t buf[sizeof(als_desc)], report[16];
	int parsed = 0, refused = 0;

	for (int n = 0; n < 20000; n++) {
		memcpy(buf, n % 2 ? als_desc : hub_desc, n % 2 ? sizeof(als_desc) : sizeof(hub_desc));
		size_t len = n % 2 ? sizeof(als_desc) : sizeof(hub_desc);
		for (int k = 0; k < 1 + n % 4; k++) {
			x ^= x << 13, x ^= x >> 7, x ^= x << 17;
			buf[x % len] = (uint8_t)(x >> 32);
		}
		x ^= x << 13, x ^= x >> 7, x ^= x << 17;
		len -= x % 3;
		struct sensor_hid_layout l;
		int r = sensor_hid_parse(buf, len, &l);
		CHECK(r == 0 || r == -ENOENT || r == -EINVAL);
		if (r != 0) {
			refused++;
			continue;
		}
		parsed++;
		for (size_t rl = 0; rl <= sizeof(report); rl++) {
			int64_t v;
			memset(report, (int)(x & 0xff), sizeof(report));
			report[0] = l.illuminance.report_id;
			size_t head = l.uses_report_ids ? 8 : 0;
			if (sensor_hid_get(&l, &l.illuminance, report, rl, &v) == 0)
				CHECK(head + l.illuminance.bit_offset + l.illuminance.bit_size <= rl * 8);
		}
	}
	printf("mutations: %d parsed, %d refused or without a sensor\n", parsed, refused);
	CHECK(parsed > 1000 && refused > 1000);
}

int main(void)
{
	test_flat();
	test_hub();
	test_refusals();
	test_bits();
	test_mutations();
	return test_report("test_sensor_hid");
}
