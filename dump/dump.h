/* dump.h - writing sky tables to files (EXR data, PNG previews, a JSON
 * manifest) and reading the EXR back, for skyd --once --dump and skyctl dump.
 *
 * Nothing here knows the daemon: a table is described by struct dump_table,
 * with the formats of proto/skyproto.h. Every function returns 0 or -errno;
 * those that take err also write there, on failure, one line saying what and
 * where (err may be NULL). Nothing prints, exits or keeps global state, so
 * different tables may be dumped from different threads at once.
 *
 * Orientation, of the EXR and, unless asked otherwise (enum dump_rows), of
 * the PNG preview:
 *   the image is W wide and H * D high; slice k of a 3-D table occupies the
 *   band of scanlines [k * H, (k + 1) * H), slice 0 at the top; inside a band
 *   scanline y = k * H + (H - 1 - j) holds table row j, so that v grows
 *   upward in an image viewer; column x is table column i.
 * Each EXR also carries string attributes: "skyd:table" (the name),
 * "skyd:size" ("WxHxD"), "skyd:uv_mapping" (SKYMAP_VERSION, decimal) and
 * "skyd:layout" (the rule above in words).
 */
#ifndef SKYD_DUMP_H
#define SKYD_DUMP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

/* One table as the daemon or a client holds it. texels: RGBA, row-major,
 * rows bottom-up in v (row 0 is v = 0), slices stacked: texel (i, j, k) at
 * index ((k * height + j) * width + i) * 4 components of 4 bytes
 * (SKY_FORMAT_RGBA32F) or 2 bytes (SKY_FORMAT_RGBA16F, IEEE binary16).
 * A binary16 table's RGB values are the stored ones times 2^rgb_scale_log2
 * (proto/skyproto.h, the slot state's rgb_scale_log2; 0 when unscaled);
 * every writer here writes the values. */
struct dump_table {
	const char *name;
	uint32_t width, height, depth;	/* depth 1 for a 2-D table */
	uint32_t format;		/* enum sky_shm_format */
	const void *texels;
	int32_t rgb_scale_log2;		/* binary16 only */
};

/* Write one table as a single-part scanline EXR, ZIP-compressed, channels
 * R, G, B, A as FLOAT (binary16 input is widened and scaled exactly). The file is
 * written as "<path>.tmp-<random>" (mode 0644 less the umask) and renamed to
 * path when complete, so it replaces an older one atomically; on failure the
 * temporary is removed and path left as it was. */
int dump_exr(const char *path, const struct dump_table *table, char *err, size_t err_size);

/* What dump_read_exr found beside the pixels. A file written by another
 * program (no skyd attributes) reads as depth 1, height = image height,
 * an empty name and uv_mapping_version 0. */
struct dump_exr_info {
	uint32_t width, height, depth;
	uint32_t uv_mapping_version;
	char name[64];			/* truncated if longer */
};

/* Read an EXR written by dump_exr (or any single-part scanline RGBA EXR)
 * back into table order: *ret_texels gets width * height * depth * 4 floats
 * at the index of struct dump_table, malloc'd, the caller frees it. HALF and
 * UINT channels are converted to float; a missing R, G or B reads 0, a
 * missing A reads 1. ret_info and ret_texels are untouched on failure. */
int dump_read_exr(const char *path, struct dump_exr_info *ret_info, float **ret_texels,
		  char *err, size_t err_size);

/* Preview tone mapping. */
enum dump_curve {
	DUMP_CURVE_ACES = 0,		/* Narkowicz's fit of the ACES RRT+ODT, white ~ 0.8 at 1 */
	DUMP_CURVE_REINHARD = 1,	/* x / (1 + x) */
};

/* Which way v runs down a PNG preview's band (a slice); the EXR always
 * has v upward. Previews are for people: a table whose v = 0 is what a
 * person expects at the top (the sky-view table's zenith) takes V_DOWN. */
enum dump_rows {
	DUMP_ROWS_V_UP = 0,		/* as the EXR: table row 0 at the bottom of its band */
	DUMP_ROWS_V_DOWN = 1,		/* table row 0 at the top of its band */
};

struct dump_tonemap {
	double exposure;		/* linear scale before the curve; <= 0: automatic */
	enum dump_curve curve;
	enum dump_rows rows;		/* 0 (V_UP) unless set */
};

/* The automatic exposure: the scale that brings the 99th percentile of the
 * table's luminance (Rec. 709 weights; negative and NaN texels count as 0)
 * to 1.0 before the curve; 1.0 when that percentile is 0 or infinite. Costs
 * one float per texel and a sort. */
int dump_auto_exposure(const struct dump_table *table, double *ret_exposure);

/* One value as dump_png encodes it: times exposure, the curve, the sRGB
 * transfer function, 8 bits; negative and NaN give 0. For a program that
 * shows frames the way dump_png writes them (skyrender's window). */
uint8_t dump_tonemap_srgb8(float x, double exposure, enum dump_curve curve);

/* Write an 8-bit sRGB PNG preview of a table (with an sRGB chunk): exposure,
 * then the curve per channel, then the sRGB transfer function; negative and
 * NaN values show black, +inf white; alpha dropped; the orientation of the
 * EXR, but for the rows of opt->rows. opt NULL means automatic exposure,
 * the ACES curve and v upward. The file is written and renamed into place
 * like dump_exr's. */
int dump_png(const char *path, const struct dump_table *table, const struct dump_tonemap *opt,
	     char *err, size_t err_size);

/* A streaming JSON writer, pretty-printed with two-space indents.
 *
 * Calls must nest validly (a key before every value inside an object, no key
 * inside an array, ends that match their begins, one top-level value); a
 * misuse, like a write or allocation error, makes the writer fail with
 * -EINVAL (-EIO, -ENOMEM) from then on, so a caller may check only
 * dump_json_finish(). Strings must be UTF-8; quotes, backslashes and control
 * characters are escaped, other bytes pass through. Numbers are written with
 * %.17g in the C locale whatever the process locale; NaN and infinities,
 * which JSON lacks, are written as null. Nesting is bounded to 32 levels. */
struct dump_json;

/* Write to f, which stays the caller's (not closed by dump_json_free). */
struct dump_json *dump_json_new_file(FILE *f);
/* Write to a growing buffer, see dump_json_buffer(). */
struct dump_json *dump_json_new_buffer(void);
/* Accepts NULL. */
void dump_json_free(struct dump_json *j);

int dump_json_begin_object(struct dump_json *j);
int dump_json_end_object(struct dump_json *j);
int dump_json_begin_array(struct dump_json *j);
int dump_json_end_array(struct dump_json *j);
int dump_json_key(struct dump_json *j, const char *key);
int dump_json_string(struct dump_json *j, const char *s);
int dump_json_number(struct dump_json *j, double x);
int dump_json_uint(struct dump_json *j, uint64_t x);
int dump_json_bool(struct dump_json *j, bool b);
int dump_json_null(struct dump_json *j);

/* Check that exactly one complete top-level value was written, end it with a
 * newline and flush a file. Returns 0 or the writer's error. */
int dump_json_finish(struct dump_json *j);

/* The text written so far to a buffer writer, NUL-terminated, its length in
 * *ret_len (may be NULL). Valid until the next call on j; NULL for a file
 * writer. */
const char *dump_json_buffer(const struct dump_json *j, size_t *ret_len);

#endif
