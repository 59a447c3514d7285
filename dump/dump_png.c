/* dump_png.c - 8-bit sRGB PNG previews of a table (libpng): exposure, tone
 * curve and the sRGB transfer function. */
#include "dump_internal.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double luminance(const float rgba[4])
{
	double y = 0.2126 * rgba[0] + 0.7152 * rgba[1] + 0.0722 * rgba[2];
	return y > 0.0 ? y : 0.0;	/* NaN too */
}

static int cmp_float(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return (x > y) - (x < y);
}

int dump_auto_exposure(const struct dump_table *t, double *ret_exposure)
{
	size_t n, at;
	float *lum, rgba[4];
	double p99;

	if (dump_table_check(t, NULL, 0) < 0 || !ret_exposure)
		return -EINVAL;
	n = (size_t)t->width * t->height * t->depth;
	lum = malloc(n * sizeof(float));
	if (!lum)
		return -ENOMEM;
	for (size_t i = 0; i < n; i++) {
		dump_texel_rgba(t, i, rgba);
		lum[i] = (float)luminance(rgba);
	}
	qsort(lum, n, sizeof(float), cmp_float);
	at = (size_t)floor(0.99 * (double)(n - 1) + 0.5);
	p99 = lum[at];
	free(lum);
	*ret_exposure = p99 > 0.0 && isfinite(p99) ? 1.0 / p99 : 1.0;
	return 0;
}

uint8_t dump_tonemap_srgb8(float x, double exposure, enum dump_curve curve)
{
	double v = x * exposure;

	if (!(v > 0.0))
		v = 0.0;
	if (v > 1e6)
		v = 1e6;	/* the rational curves would meet inf / inf */
	if (curve == DUMP_CURVE_REINHARD)
		v = v / (1.0 + v);
	else
		v = v * (2.51 * v + 0.03) / (v * (2.43 * v + 0.59) + 0.14);
	v = v > 1.0 ? 1.0 : v;
	v = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
	return (uint8_t)(v * 255.0 + 0.5);
}

struct png_err {
	char msg[200];
	int saved_errno;
};

static void png_on_error(png_structp png, png_const_charp msg)
{
	struct png_err *pe = png_get_error_ptr(png);

	pe->saved_errno = errno;	/* libpng's own write error follows fwrite's */
	snprintf(pe->msg, sizeof(pe->msg), "%s", msg);
	png_longjmp(png, 1);
}

static void png_on_warning(png_structp png, png_const_charp msg)
{
}

/* Table row of image scanline y: dump.h's order, or with v downward each
 * band's rows in storage order. */
static size_t preview_row(const struct dump_table *t, uint32_t y, enum dump_rows rows)
{
	return rows == DUMP_ROWS_V_DOWN ? y : dump_scanline_row(t, y);
}

/* All the libpng calls that may longjmp, kept apart so that no local of the
 * caller lives across setjmp. */
static int png_encode(png_structp png, png_infop info, FILE *f, const struct dump_table *t,
		      double exposure, enum dump_curve curve, enum dump_rows rows, uint8_t *row)
{
	uint32_t image_h = t->height * t->depth;
	float rgba[4];

	if (setjmp(png_jmpbuf(png)))
		return -1;
	png_init_io(png, f);
	png_set_IHDR(png, info, t->width, image_h, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
		     PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
	png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
	png_write_info(png, info);
	for (uint32_t y = 0; y < image_h; y++) {
		size_t base = preview_row(t, y, rows) * t->width;
		for (uint32_t i = 0; i < t->width; i++) {
			dump_texel_rgba(t, base + i, rgba);
			for (int c = 0; c < 3; c++)
				row[3 * i + c] = dump_tonemap_srgb8(rgba[c], exposure, curve);
		}
		png_write_row(png, row);
	}
	png_write_end(png, NULL);
	return 0;
}

int dump_png(const char *path, const struct dump_table *t, const struct dump_tonemap *opt,
	     char *err, size_t err_size)
{
	enum dump_curve curve = opt ? opt->curve : DUMP_CURVE_ACES;
	enum dump_rows rows = opt ? opt->rows : DUMP_ROWS_V_UP;
	double exposure = opt ? opt->exposure : 0.0;
	struct png_err pe = { .msg = "" };
	struct dump_out out;
	png_structp png = NULL;
	png_infop info = NULL;
	uint8_t *row = NULL;
	FILE *f = NULL;
	int r;

	if ((r = dump_table_check(t, err, err_size)) < 0)
		return r;
	if (!path || (curve != DUMP_CURVE_ACES && curve != DUMP_CURVE_REINHARD) || !isfinite(exposure) ||
	    (rows != DUMP_ROWS_V_UP && rows != DUMP_ROWS_V_DOWN))
		return dump_fail(err, err_size, -EINVAL, "dump: '%s': bad path or tone mapping", t->name);
	if (!(exposure > 0.0) && (r = dump_auto_exposure(t, &exposure)) < 0)
		return dump_fail(err, err_size, r, "'%s': exposure: %s", path, strerror(-r));

	if ((r = dump_out_open(&out, path, err, err_size)) < 0)
		return r;
	f = fdopen(out.fd, "wb");
	if (!f) {
		r = dump_fail(err, err_size, -errno, "'%s': %s", path, strerror(errno));
		goto out;
	}
	out.fd = -1;	/* f owns it */
	row = malloc(3 * (size_t)t->width);
	png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &pe, png_on_error, png_on_warning);
	info = png ? png_create_info_struct(png) : NULL;
	if (!row || !info) {
		r = dump_fail(err, err_size, -ENOMEM, "'%s': out of memory", path);
		goto out;
	}
	errno = 0;	/* so that png_on_error sees only a write's errno */
	if (png_encode(png, info, f, t, exposure, curve, rows, row) < 0) {
		r = dump_fail(err, err_size, pe.saved_errno ? -pe.saved_errno : -EIO, "'%s': png: %s%s%s%s",
			      path, pe.msg, pe.saved_errno ? " (" : "",
			      pe.saved_errno ? strerror(pe.saved_errno) : "", pe.saved_errno ? ")" : "");
		goto out;
	}
out:
	png_destroy_write_struct(&png, &info);
	if (f && fclose(f) != 0 && r == 0)
		r = dump_fail(err, err_size, -errno, "'%s': %s", path, strerror(errno));
	free(row);
	if (r == 0)
		r = dump_out_commit(&out, path, err, err_size);
	if (r < 0)
		dump_out_abort(&out);
	return r;
}
