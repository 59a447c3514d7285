/* dump.c - what the writers and the reader of dump/ share: a table checked,
 * its texels as float RGBA, the image's scanline order, files written under
 * a temporary name and renamed into place, and the error text. */
#include "dump_internal.h"

#include <assert.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/random.h>
#include <unistd.h>

#include "skyproto.h"

int dump_fail(char *err, size_t err_size, int r, const char *fmt, ...)
{
	if (err && err_size) {
		va_list ap;
		va_start(ap, fmt);
		vsnprintf(err, err_size, fmt, ap);
		va_end(ap);
	}
	return r;
}

/* Tables ---------------------------------------------------------------- */

static size_t texel_bytes(uint32_t format)
{
	return format == SKY_FORMAT_RGBA32F ? 16 : format == SKY_FORMAT_RGBA16F ? 8 : 0;
}

/* The image is W x H*D; both must fit the int32 coordinates of EXR and PNG,
 * and the texel count a size_t, so that no index below can overflow. */
int dump_table_check(const struct dump_table *t, char *err, size_t err_size)
{
	if (!t || !t->name || !t->texels)
		return dump_fail(err, err_size, -EINVAL, "dump: no table");
	if (!texel_bytes(t->format))
		return dump_fail(err, err_size, -EINVAL, "dump: table '%s': unknown format %u",
				 t->name, t->format);
	if (!t->width || !t->height || !t->depth || t->width > INT32_MAX ||
	    (uint64_t)t->height * t->depth > INT32_MAX ||
	    (uint64_t)t->width * t->height * t->depth > SIZE_MAX / 16)
		return dump_fail(err, err_size, -EINVAL, "dump: table '%s': bad size %ux%ux%u",
				 t->name, t->width, t->height, t->depth);
	return 0;
}

/* Table row of image scanline y, as documented in dump.h. */
size_t dump_scanline_row(const struct dump_table *t, uint32_t y)
{
	uint32_t k = y / t->height, j = t->height - 1 - y % t->height;
	return (size_t)k * t->height + j;
}

static float half_to_float(uint16_t h)
{
	uint32_t sign = (uint32_t)(h & 0x8000u) << 16, e = (h >> 10) & 0x1fu, m = h & 0x3ffu, bits;
	float f;

	if (e == 0x1f) {
		bits = sign | 0x7f800000u | m << 13;
	} else if (e) {
		bits = sign | (e + 112) << 23 | m << 13;
	} else if (!m) {
		bits = sign;
	} else {
		/* Subnormal half: every one is a normal float. */
		e = 113;
		while (!(m & 0x400u)) {
			m <<= 1;
			e--;
		}
		bits = sign | e << 23 | (m & 0x3ffu) << 13;
	}
	memcpy(&f, &bits, sizeof(f));
	return f;
}

void dump_texel_rgba(const struct dump_table *t, size_t index, float ret[4])
{
	if (t->format == SKY_FORMAT_RGBA32F) {
		memcpy(ret, (const float *)t->texels + index * 4, 4 * sizeof(float));
	} else {
		const uint16_t *h = (const uint16_t *)t->texels + index * 4;
		for (int c = 0; c < 4; c++)
			ret[c] = half_to_float(h[c]);
		/* A power of two: exact unless it leaves the float range. */
		for (int c = 0; c < 3 && t->rgb_scale_log2; c++)
			ret[c] = ldexpf(ret[c], t->rgb_scale_log2);
	}
}

/* Output files ---------------------------------------------------------- */

int dump_out_open(struct dump_out *o, const char *path, char *err, size_t err_size)
{
	o->fd = -1;
	for (int attempt = 0; attempt < 16; attempt++) {
		uint32_t salt = 0;

		if (getrandom(&salt, sizeof(salt), GRND_NONBLOCK) < 0)
			salt = (uint32_t)getpid() * 2654435761u + (uint32_t)attempt;
		if ((size_t)snprintf(o->tmp, sizeof(o->tmp), "%s.tmp-%08x", path, salt) >= sizeof(o->tmp))
			return dump_fail(err, err_size, -ENAMETOOLONG, "'%s': %s", path, strerror(ENAMETOOLONG));
		o->fd = open(o->tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOCTTY, 0644);
		if (o->fd >= 0)
			return 0;
		if (errno != EEXIST)
			break;
	}
	return dump_fail(err, err_size, -errno, "'%s': %s", path, strerror(errno));
}

int dump_out_commit(struct dump_out *o, const char *path, char *err, size_t err_size)
{
	assert(o->fd < 0);
	if (rename(o->tmp, path) == 0)
		return 0;
	int r = dump_fail(err, err_size, -errno, "'%s': rename: %s", path, strerror(errno));
	unlink(o->tmp);
	return r;
}

void dump_out_abort(struct dump_out *o)
{
	if (o->fd >= 0)
		close(o->fd);
	o->fd = -1;
	unlink(o->tmp);
}
