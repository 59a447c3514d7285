/* bench_accuracy_image.c - the fisheye images of `skybench accuracy`: tables,
 * ground truth and signed error side by side, as PNG. */
#include "bench_accuracy_internal.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdlib.h>
#include <string.h>

static int write_png(const char *path, const uint8_t *rgb, int w, int h)
{
	FILE *f = fopen(path, "wbe");
	if (!f)
		return -errno;
	png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
	png_infop info = png ? png_create_info_struct(png) : NULL;
	int rc = -ENOMEM;
	if (png && info) {
		rc = -EIO;
		if (!setjmp(png_jmpbuf(png))) {
			png_init_io(png, f);
			png_set_IHDR(png, info, w, h, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
				     PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
			png_write_info(png, info);
			for (int y = 0; y < h; y++)
				png_write_row(png, (png_const_bytep)(rgb + (size_t)y * w * 3));
			png_write_end(png, NULL);
			rc = 0;
		}
	}
	png_destroy_write_struct(&png, &info);
	if (fclose(f) != 0 && rc == 0)
		rc = -errno;
	return rc;
}

static uint8_t srgb8(double x)
{
	x = x < 0 ? 0 : x > 1 ? 1 : x;
	double v = x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1 / 2.4) - 0.055;
	return (uint8_t)lrint(255.0 * v);
}

/* Fisheye pixel -> direction: zenith in the middle, the horizon on the
 * rim, north up and east to the right (the dome seen from above). */
static bool fisheye_dir(double x, double y, double *el, double *az)
{
	double r = sqrt(x * x + y * y);
	if (r > 1.0)
		return false;
	*el = 90.0 * (1.0 - r);
	*az = atan2(x, y) * 180.0 / M_PI;
	if (*az < 0)
		*az += 360.0;
	return true;
}

/* Signed relative error to a colour: blue (tables low) through white to
 * red (tables high), saturating at +-scale. */
static void error_colour(double rel, double scale, uint8_t *p)
{
	double t = rel / scale;
	t = t < -1 ? -1 : t > 1 ? 1 : t;
	double r = t > 0 ? 1 : 1 + t, gch = 1 - fabs(t), b = t < 0 ? 1 : 1 - t;
	p[0] = (uint8_t)lrint(255 * r);
	p[1] = (uint8_t)lrint(255 * (0.15 + 0.85 * gch));
	p[2] = (uint8_t)lrint(255 * b);
}

int acc_fisheye(const struct opts *o, struct eng *e, const struct scene *sc)
{
	int n = o->fisheye_n, px = o->image_px, gap = 8;
	static struct gt g;
	struct sky_state s;

	g.n = 0;
	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			double el, az;
			if (fisheye_dir(2.0 * (i + 0.5) / n - 1, 1 - 2.0 * (j + 0.5) / n, &el, &az) &&
			    el >= 0.25 && g.n < MAX_DIRS) {
				g.dir[g.n] = (struct pt_dir){ el, az };
				g.weight[g.n++] = 1;
			}
		}
	int rc = acc_ground_truth(o, sc, o->fisheye_error, &g, "fisheye");
	if (rc < 0)
		return rc;
	double t_ms;
	if (acc_scene_state(sc, &acc_configs[DEFAULT_CONFIG], &s) < 0 || acc_time_tables(e, &s, 0, &t_ms) < 0)
		return -EIO;
	/* One exposure for both radiance panels, from the truth. */
	double lums[MAX_DIRS];
	for (size_t i = 0; i < g.n; i++)
		lums[i] = g.lum[i];
	qsort(lums, g.n, sizeof(lums[0]), cmp_double);
	double exposure = g.n && lums[g.n / 2] > 0 ? 0.4 / lums[g.n / 2] : 1.0;

	int w = 3 * px + 2 * gap;
	uint8_t *img = calloc((size_t)w * px * 3, 1);
	if (!img)
		return -ENOMEM;
	memset(img, 40, (size_t)w * px * 3);
	size_t k = 0;
	int *cell = calloc((size_t)n * n, sizeof(int));
	if (!cell) {
		free(img);
		return -ENOMEM;
	}
	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			double el, az;
			bool in = fisheye_dir(2.0 * (i + 0.5) / n - 1, 1 - 2.0 * (j + 0.5) / n, &el, &az) &&
				  el >= 0.25;
			cell[j * n + i] = in ? (int)k++ : -1;
		}
	for (int y = 0; y < px; y++)
		for (int x = 0; x < px; x++) {
			double el, az, rgb[3];
			if (!fisheye_dir(2.0 * (x + 0.5) / px - 1, 1 - 2.0 * (y + 0.5) / px, &el, &az))
				continue;
			acc_table_radiance(e, &s, el, az, rgb);
			uint8_t *p = img + ((size_t)y * w + x) * 3;
			for (int c = 0; c < 3; c++)
				p[c] = srgb8(1 - exp(-exposure * rgb[c]));
			int ci = cell[(y * n / px) * n + x * n / px];
			if (ci < 0)
				continue;
			p = img + ((size_t)y * w + px + gap + x) * 3;
			for (int c = 0; c < 3; c++)
				p[c] = srgb8(1 - exp(-exposure * g.rgb[ci][c]));
			acc_table_radiance(e, &s, g.dir[ci].elevation_deg, g.dir[ci].azimuth_deg, rgb);
			double yt = luminance(rgb);
			p = img + ((size_t)y * w + 2 * (px + gap) + x) * 3;
			error_colour(g.lum[ci] > 0 ? (yt - g.lum[ci]) / g.lum[ci] : 0, 0.2, p);
		}
	char path[4096];
	rc = FITS(path, "%s/fisheye-%s.png", o->out, sc->name) ? write_png(path, img, w, px)
							       : -ENAMETOOLONG;
	if (rc < 0)
		fprintf(stderr, "skybench: '%s': %s\n", path, strerror(-rc));
	free(cell);
	free(img);
	return rc;
}
