/* terrain_png.h - height fields written by the tests themselves, so that no
 * image is committed: greyscale (or colour, to be refused) PNGs by libpng,
 * SKYTERRAIN16 raw files, and a PNG cut short. Needs libpng
 * (PkgConfig::PNG). */
#ifndef SKYD_TERRAIN_PNG_H
#define SKYD_TERRAIN_PNG_H

#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Writes a w x h PNG of the given bit depth (1, 2, 4, 8 or 16) and colour
 * type (PNG_COLOR_TYPE_GRAY, _GRAY_ALPHA or _RGB) whose grey (or each
 * colour) sample at (i, j) is texels[j * w + i] reduced to the depth
 * (its top bits). interlace: Adam7. header_only stops after the header
 * (a file cut short, or one that claims a size it never holds). Returns 0
 * or -1. */
static inline int terrain_png_write(const char *path, uint32_t w, uint32_t h, int depth, int type,
				    const uint16_t *texels, int interlace, int header_only)
{
	FILE *f = fopen(path, "wb");
	if (!f)
		return -1;
	png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
	png_infop info = png ? png_create_info_struct(png) : NULL;
	int channels = type == PNG_COLOR_TYPE_GRAY ? 1 : type == PNG_COLOR_TYPE_GRAY_ALPHA ? 2 : 3;
	size_t row_bytes = ((size_t)w * channels * depth + 7) / 8;
	uint8_t *row = calloc(row_bytes ? row_bytes : 1, 1);
	if (!png || !info || !row || setjmp(png_jmpbuf(png))) {
		png_destroy_write_struct(&png, &info);
		free(row);
		fclose(f);
		return -1;
	}
	png_init_io(png, f);
	png_set_compression_level(png, 1);
	png_set_IHDR(png, info, w, h, depth, type,
		     interlace ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
		     PNG_FILTER_TYPE_DEFAULT);
	png_write_info(png, info);
	if (!header_only) {
		int passes = png_set_interlace_handling(png);
		for (int pass = 0; pass < passes; pass++)
			for (uint32_t j = 0; j < h; j++) {
				memset(row, 0, row_bytes);
				for (uint32_t i = 0; i < w; i++)
					for (int c = 0; c < channels; c++) {
						uint32_t v = texels[(size_t)j * w + i] >> (16 - depth);
						if (type == PNG_COLOR_TYPE_GRAY_ALPHA && c == 1)
							v = (1u << depth) - 1u;	/* opaque */
						size_t bit = ((size_t)i * channels + c) * depth;
						if (depth == 16) {
							row[bit / 8] = (uint8_t)(v >> 8);
							row[bit / 8 + 1] = (uint8_t)v;
						} else {
							row[bit / 8] |= (uint8_t)(v << (8 - depth - bit % 8));
						}
					}
				png_write_row(png, row);
			}
		png_write_end(png, NULL);
	}
	png_destroy_write_struct(&png, &info);
	free(row);
	return fclose(f) == 0 ? 0 : -1;
}

/* A SKYTERRAIN16 raw file of w x h texels; extra bytes appended (or, with
 * extra < 0, the last -extra bytes left out). Returns 0 or -1. */
static inline int terrain_raw_write(const char *path, uint32_t w, uint32_t h,
				    const uint16_t *texels, long extra)
{
	FILE *f = fopen(path, "wb");
	if (!f)
		return -1;
	fprintf(f, "SKYTERRAIN16 %u %u\n", w, h);
	long n = (long)w * h * 2 + extra;
	for (long k = 0; k < n; k++) {
		size_t i = (size_t)k / 2;
		fputc(i < (size_t)w * h ? (k % 2 ? texels[i] >> 8 : texels[i] & 0xff) : 0, f);
	}
	return fclose(f) == 0 ? 0 : -1;
}

/* Cuts the file at path down to keep bytes. */
static inline int terrain_file_cut(const char *path, long keep)
{
	return truncate(path, keep);
}

#endif
