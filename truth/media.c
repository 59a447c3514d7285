/* media.c - a sky state's clouds and terrain as the path tracer's scene,
 * and the synthetic height fields of the accuracy scenes and stiff cases
 * (media.h). */
#include "media.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "terrain.h"

const char *const media_terrain_names[MEDIA_N_TERRAINS] = { "ridge", "cliff" };

bool media_present(const struct sky_state *s)
{
	return state_clouds_drawn(s) > 0 || state_terrain_set(s);
}

int media_from_state(const struct sky_state *s, struct media *ret, char *err, size_t err_size)
{
	memset(ret, 0, sizeof(*ret));
	ret->scene.view = PT_VIEW_AIR;
	ret->scene.n_layers = state_cloud_layers_double(s, ret->scene.layers);
	state_cloud_offset_km(s, ret->scene.offset_km);
	if (!state_terrain_set(s))
		return 0;
	int r = state_terrain_get(s, &ret->terrain, &ret->view, err, err_size);
	if (r < 0)
		return r;
	ret->scene.terrain = &ret->view;
	return 0;
}

void media_finish(struct media *m)
{
	terrain_unref(m->terrain);
	memset(m, 0, sizeof(*m));
}

int media_write_raw(const char *path, const uint16_t *texels, uint32_t width)
{
	FILE *f = fopen(path, "wbe");
	if (!f)
		return -errno;
	fprintf(f, "SKYTERRAIN16 %u %u\n", width, width);
	for (size_t i = 0; i < (size_t)width * width; i++) {
		fputc(texels[i] & 0xff, f);
		fputc(texels[i] >> 8, f);
	}
	int bad = ferror(f);
	if (fclose(f) != 0 || bad)
		return -EIO;
	return 0;
}

/* smoothstep of x over [a, b]. */
static double smooth(double a, double b, double x)
{
	double u = fmin(fmax((x - a) / (b - a), 0.0), 1.0);
	return u * u * (3.0 - 2.0 * u);
}

/* Texel (i, j) of a field of width w over a square of side e km: its
 * centre's east and north km. */
static void centre(uint32_t i, uint32_t j, uint32_t w, double e, double *x, double *y)
{
	*x = -0.5 * e + (i + 0.5) * e / w;
	*y = 0.5 * e - (j + 0.5) * e / w;
}

static void fill_ridge(uint16_t *t, uint32_t w)
{
	for (uint32_t j = 0; j < w; j++)
		for (uint32_t i = 0; i < w; i++) {
			double x, y;
			centre(i, j, w, 40.0, &x, &y);
			double across = (y + 6.0) / 1.5;
			double h = exp(-0.5 * across * across) * (1.0 - smooth(14.0, 19.0, fabs(x)));
			t[j * w + i] = (uint16_t)lround(65535.0 * h);
		}
}

static void fill_cliff(uint16_t *t, uint32_t w)
{
	for (uint32_t j = 0; j < w; j++)
		for (uint32_t i = 0; i < w; i++)
			t[j * w + i] = i >= w / 2 + 1 ? 65535 : 0;
}

/* The process's directory of fields and its files, removed at exit. */
static char dir[256];
static char paths[MEDIA_N_TERRAINS][320];

static void remove_files(void)
{
	for (int k = 0; k < MEDIA_N_TERRAINS; k++)
		if (paths[k][0])
			unlink(paths[k]);
	if (dir[0])
		rmdir(dir);
}

const char *media_terrain_path(enum media_terrain terrain)
{
	static const uint32_t widths[MEDIA_N_TERRAINS] = { 256, 64 };

	if ((int)terrain < 0 || terrain >= MEDIA_N_TERRAINS) {
		errno = EINVAL;
		return NULL;
	}
	if (paths[terrain][0] && access(paths[terrain], R_OK) == 0)
		return paths[terrain];
	if (!dir[0]) {
		const char *tmp = getenv("TMPDIR");
		snprintf(dir, sizeof(dir), "%s/skyd-media-XXXXXX", tmp && *tmp == '/' ? tmp : "/tmp");
		if (!mkdtemp(dir)) {
			dir[0] = 0;
			return NULL;
		}
		atexit(remove_files);
	}
	uint32_t w = widths[terrain];
	uint16_t *t = malloc(sizeof(uint16_t) * w * w);
	if (!t)
		return NULL;
	(terrain == MEDIA_RIDGE ? fill_ridge : fill_cliff)(t, w);
	snprintf(paths[terrain], sizeof(paths[terrain]), "%s/%s.raw", dir, media_terrain_names[terrain]);
	int r = media_write_raw(paths[terrain], t, w);
	free(t);
	if (r < 0) {
		paths[terrain][0] = 0;
		errno = -r;
		return NULL;
	}
	return paths[terrain];
}

const char *media_expand_key(const char *kv, char *buf, size_t size)
{
	if (strncmp(kv, "terrain=@", 9) != 0)
		return kv;
	for (int t = 0; t < MEDIA_N_TERRAINS; t++)
		if (!strcmp(kv + 9, media_terrain_names[t])) {
			const char *path = media_terrain_path((enum media_terrain)t);
			if (!path)
				return NULL;
			if (snprintf(buf, size, "terrain=%s", path) >= (int)size) {
				errno = ENAMETOOLONG;
				return NULL;
			}
			return buf;
		}
	errno = EINVAL;
	return NULL;
}
