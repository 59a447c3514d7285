/* fuzz_hid.c - libFuzzer target for what a USB light sensor of the HID
 * family sends (sensor/sensor_hidrd.c, as sensor/sensor_hid.c uses it):
 * a report descriptor, then reports. The input is a 16-bit little-endian
 * length, the descriptor of that length, then reports, each a length byte
 * and its bytes. Each report is read as an input report, and as a feature
 * report of each id into which skyd writes its settings. Built without
 * libFuzzer, a main() replays the files named on the command line
 * (fuzz_replay.h). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sensor_internal.h"

static volatile int64_t sink;

/* As sensor_hid.c's set_properties: the settings written into a copy of
 * a feature report of the size the descriptor gives its id. */
static void put_features(const struct sensor_hid_layout *l, const uint8_t *report, size_t len)
{
	const struct sensor_hid_field *fields[] = { &l->reporting_state, &l->power_state,
						    &l->report_interval, &l->sensitivity_abs,
						    &l->sensitivity_rel };
	uint8_t buf[4096 + 1];

	for (size_t i = 0; i < sizeof(fields) / sizeof(fields[0]); i++) {
		const struct sensor_hid_field *f = fields[i];
		if (!f->present)
			continue;
		uint32_t bytes = sensor_hid_report_bytes(l, SENSOR_HID_FEATURE, f->report_id);
		if (bytes > sizeof(buf) || len < bytes)
			continue;	/* feature_got refuses it likewise */
		memcpy(buf, report, bytes);
		sensor_hid_put(l, f, buf, bytes, f->wanted);
		int64_t v;
		if (sensor_hid_get(l, f, buf, bytes, &v) == 0)
			sink += v;
	}
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	struct sensor_hid_layout *l = malloc(sizeof(*l));
	double scale;

	if (!l)
		abort();
	if (size < 2)
		goto out;
	size_t n = (size_t)data[0] | (size_t)data[1] << 8;
	if (n > size - 2)
		n = size - 2;
	/* Each piece in a buffer of its own: a read past its end is found. */
	uint8_t *desc = malloc(n ? n : 1);
	if (!desc)
		abort();
	memcpy(desc, data + 2, n);
	int r = sensor_hid_parse(desc, n, l);
	free(desc);
	if (r < 0)
		goto out;
	sink += sensor_hid_lux_scale(&l->illuminance, &scale);
	for (size_t i = 2 + n; i < size;) {
		size_t len = data[i++];
		if (len > size - i)
			len = size - i;
		uint8_t *report = malloc(len ? len : 1);
		if (!report)
			abort();
		memcpy(report, data + i, len);
		int64_t v = 0;
		sink += sensor_hid_input(l, report, len, &v) + v;
		put_features(l, report, len);
		free(report);
		i += len;
	}
out:
	free(l);
	return 0;
}

#include "fuzz_replay.h"
