/* terrain.c - reading a terrain height field (terrain.h): the file's
 * checks, the PNG and SKYTERRAIN16 readers, the hash and the one-entry
 * cache of the last field read. */
#include "terrain.h"

#include <errno.h>
#include <fcntl.h>
#include <png.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

struct terrain {
	atomic_uint refs;
	uint32_t width, height;
	uint16_t max_texel;
	uint64_t hash;
	uint16_t texels[];
};

static int fail(int code, char *err, size_t err_size, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));
static int fail(int code, char *err, size_t err_size, const char *fmt, ...)
{
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(err, err_size, fmt, ap);
	va_end(ap);
	return code;
}

/* ---- the field ---- */

uint64_t terrain_hash_texels(const uint16_t *texels, uint32_t width, uint32_t height)
{
	uint64_t h = 0xcbf29ce484222325ull;
	const uint64_t prime = 0x100000001b3ull;
	uint32_t dims[2] = { width, height };

	for (int k = 0; k < 2; k++)
		for (int b = 0; b < 4; b++)
			h = (h ^ ((dims[k] >> (8 * b)) & 0xffu)) * prime;
	for (size_t i = 0, n = (size_t)width * height; i < n; i++) {
		h = (h ^ (texels[i] & 0xffu)) * prime;
		h = (h ^ (texels[i] >> 8)) * prime;
	}
	return h;
}

static struct terrain *field_new(uint32_t width, uint32_t height)
{
	struct terrain *t = malloc(sizeof(*t) + sizeof(uint16_t) * (size_t)width * height);

	if (!t)
		return NULL;
	atomic_init(&t->refs, 1);
	t->width = width;
	t->height = height;
	return t;
}

/* The hash and the largest texel, once the texels are in. */
static void field_finish(struct terrain *t)
{
	uint16_t m = 0;

	for (size_t i = 0, n = (size_t)t->width * t->height; i < n; i++)
		m = t->texels[i] > m ? t->texels[i] : m;
	t->max_texel = m;
	t->hash = terrain_hash_texels(t->texels, t->width, t->height);
}

struct terrain *terrain_ref(struct terrain *t)
{
	atomic_fetch_add(&t->refs, 1);
	return t;
}

void terrain_unref(struct terrain *t)
{
	if (t && atomic_fetch_sub(&t->refs, 1) == 1)
		free(t);
}

uint32_t terrain_width(const struct terrain *t)
{
	return t->width;
}

uint32_t terrain_height(const struct terrain *t)
{
	return t->height;
}

uint64_t terrain_hash(const struct terrain *t)
{
	return t->hash;
}

const uint16_t *terrain_texels(const struct terrain *t)
{
	return t->texels;
}

void terrain_view(const struct terrain *t, double extent_km, double height_km,
		  struct skyterrain *ret)
{
	*ret = (struct skyterrain){ .texels = t->texels, .width = t->width, .height = t->height,
				    .max_texel = t->max_texel, .extent_km = extent_km,
				    .height_km = height_km };
}

/* The size rules both formats share: -EFBIG past the bound, -EINVAL when
 * empty or not square. */
static int check_size(const char *path, uint32_t w, uint32_t h, char *err, size_t err_size)
{
	if (w > SKYTERRAIN_MAX_TEXELS || h > SKYTERRAIN_MAX_TEXELS)
		return fail(-EFBIG, err, err_size, "'%s' is %u x %u texels, more than %d x %d", path, w,
			    h, SKYTERRAIN_MAX_TEXELS, SKYTERRAIN_MAX_TEXELS);
	if (w == 0 || h == 0 || w != h)
		return fail(-EINVAL, err, err_size, "'%s' is %u x %u texels; a height field is square",
			    path, w, h);
	return 0;
}

/* ---- PNG (libpng) ---- */

/* libpng reports errors by longjmp: what the error handler saw and the
 * field being read live here, on the heap, so that nothing the jump
 * leaves behind is an automatic variable changed after setjmp. */
struct png_job {
	const char *path;
	char message[160];
	struct terrain *t;
	png_bytep *rows;
	int code;
	char *err;
	size_t err_size;
};

static void png_error_fn(png_structp png, png_const_charp msg)
{
	struct png_job *j = png_get_error_ptr(png);

	snprintf(j->message, sizeof(j->message), "%s", msg);
	png_longjmp(png, 1);
}

static void png_warning_fn(png_structp png, png_const_charp msg)
{
	(void)png;
	(void)msg;	/* ancillary trouble (a bad gAMA, a CRC in a text chunk) changes no height */
}

/* After the header: the checks, the transformations to one channel of
 * 8 or 16 bits, the field and the rows. 0 or -errno with j->err. */
static int png_prepare(struct png_job *j, png_structp png, png_infop info)
{
	uint32_t w = png_get_image_width(png, info), h = png_get_image_height(png, info);
	int type = png_get_color_type(png, info), depth = png_get_bit_depth(png, info);
	int r = check_size(j->path, w, h, j->err, j->err_size);

	if (r < 0)
		return r;
	if (type != PNG_COLOR_TYPE_GRAY && type != PNG_COLOR_TYPE_GRAY_ALPHA)
		return fail(-EINVAL, j->err, j->err_size,
			    "'%s' is a colour PNG; a height field is greyscale", j->path);
	if (depth < 8)
		png_set_expand_gray_1_2_4_to_8(png);
	if (type == PNG_COLOR_TYPE_GRAY_ALPHA)
		png_set_strip_alpha(png);
	png_set_interlace_handling(png);
	png_read_update_info(png, info);
	size_t bytes = png_get_rowbytes(png, info);
	if (bytes != (size_t)w * (depth == 16 ? 2 : 1))
		return fail(-EINVAL, j->err, j->err_size, "'%s': unexpected PNG row layout", j->path);
	j->t = field_new(w, h);
	j->rows = malloc(sizeof(png_bytep) * h);
	if (!j->t || !j->rows)
		return fail(-ENOMEM, j->err, j->err_size, "'%s': out of memory", j->path);
	/* 16-bit rows fill the texels' bytes; 8-bit rows their first half,
	 * widened afterwards. */
	uint8_t *base = (uint8_t *)j->t->texels;
	for (uint32_t y = 0; y < h; y++)
		j->rows[y] = base + (size_t)y * bytes;
	return 0;
}

/* PNG's big-endian 16-bit samples, or 8-bit ones times 257 (255 -> 65535),
 * into texels, in place. */
static void png_widen(struct terrain *t, int depth)
{
	size_t n = (size_t)t->width * t->height;
	uint8_t *b = (uint8_t *)t->texels;

	if (depth == 16) {
		for (size_t i = 0; i < n; i++)
			t->texels[i] = (uint16_t)(b[2 * i] << 8 | b[2 * i + 1]);
		return;
	}
	/* Backwards: texel i's bytes 2i, 2i + 1 lie at or past byte i. */
	for (size_t i = n; i-- > 0;)
		t->texels[i] = (uint16_t)(b[i] * 257u);
}

static int png_run(struct png_job *j, FILE *f)
{
	png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, j, png_error_fn,
						 png_warning_fn);
	png_infop info = png ? png_create_info_struct(png) : NULL;

	if (!png || !info) {
		png_destroy_read_struct(&png, NULL, NULL);
		return fail(-ENOMEM, j->err, j->err_size, "'%s': out of memory", j->path);
	}
	if (setjmp(png_jmpbuf(png))) {
		png_destroy_read_struct(&png, &info, NULL);
		if (j->code == 0)
			j->code = fail(-EINVAL, j->err, j->err_size, "'%s': truncated or corrupt PNG (%s)",
				       j->path, j->message);
		return j->code;
	}
	png_init_io(png, f);
	png_set_user_limits(png, SKYTERRAIN_MAX_TEXELS, SKYTERRAIN_MAX_TEXELS);
	png_read_info(png, info);
	int depth = png_get_bit_depth(png, info);
	j->code = png_prepare(j, png, info);
	if (j->code == 0) {
		png_read_image(png, j->rows);
		png_read_end(png, NULL);
		png_widen(j->t, depth);
	}
	png_destroy_read_struct(&png, &info, NULL);
	return j->code;
}

static int read_png(const char *path, FILE *f, struct terrain **ret, char *err, size_t err_size)
{
	struct png_job *j = calloc(1, sizeof(*j));
	int r;

	if (!j)
		return fail(-ENOMEM, err, err_size, "'%s': out of memory", path);
	*j = (struct png_job){ .path = path, .err = err, .err_size = err_size };
	r = png_run(j, f);
	free(j->rows);
	if (r < 0)
		terrain_unref(j->t);
	else
		*ret = j->t;
	free(j);
	return r;
}

/* ---- SKYTERRAIN16 ---- */

/* A decimal without sign or leading zero, at most 9 digits; the pointer
 * past it, or NULL. */
static const char *parse_dim(const char *s, uint32_t *ret)
{
	uint32_t v = 0;
	int n = 0;

	if (*s == '0' && s[1] >= '0' && s[1] <= '9')
		return NULL;
	for (; *s >= '0' && *s <= '9' && n < 9; s++, n++)
		v = v * 10 + (uint32_t)(*s - '0');
	if (n == 0 || (*s >= '0' && *s <= '9'))
		return NULL;
	*ret = v;
	return s;
}

static int read_raw(const char *path, FILE *f, off_t file_bytes, struct terrain **ret, char *err,
		    size_t err_size)
{
	char line[64];
	uint32_t w, h;
	const char *p;

	if (!fgets(line, sizeof(line), f) || strncmp(line, TERRAIN_RAW_MAGIC " ", 13) != 0 ||
	    !(p = parse_dim(line + 13, &w)) || *p++ != ' ' || !(p = parse_dim(p, &h)) ||
	    strcmp(p, "\n") != 0)
		return fail(-EINVAL, err, err_size,
			    "'%s': the first line is not '" TERRAIN_RAW_MAGIC " <width> <height>'", path);
	int r = check_size(path, w, h, err, err_size);
	if (r < 0)
		return r;
	size_t want = (size_t)w * h * 2, header = strlen(line);
	if ((size_t)file_bytes != header + want)
		return fail(-EINVAL, err, err_size, "'%s' holds %lld bytes of texels where %u x %u need %zu",
			    path, (long long)file_bytes - (long long)header, w, h, want);
	struct terrain *t = field_new(w, h);
	if (!t)
		return fail(-ENOMEM, err, err_size, "'%s': out of memory", path);
	uint8_t *b = (uint8_t *)t->texels;
	if (fread(b, 1, want, f) != want) {
		terrain_unref(t);
		return fail(-EINVAL, err, err_size, "'%s': cannot read its texels", path);
	}
	for (size_t i = 0, n = (size_t)w * h; i < n; i++)
		t->texels[i] = (uint16_t)(b[2 * i] | b[2 * i + 1] << 8);
	*ret = t;
	return 0;
}

/* ---- the file ---- */

/* The path's own rules, before the file is touched. */
static int check_path(const char *path, char *err, size_t err_size)
{
	size_t n = strlen(path);

	if (n >= TERRAIN_PATH_MAX)
		return fail(-EINVAL, err, err_size, "a path of %zu bytes, more than %d", n,
			    TERRAIN_PATH_MAX - 1);
	for (size_t i = 0; i < n; i++)
		if ((unsigned char)path[i] < 0x20 || (unsigned char)path[i] > 0x7e)
			return fail(-EINVAL, err, err_size,
				    "byte %zu of the path is 0x%02x, not printable ASCII", i,
				    (unsigned char)path[i]);
	if (path[0] != '/')
		return fail(-EINVAL, err, err_size,
			    "'%s' is not an absolute path (skyd's directory is not the client's)", path);
	return 0;
}

/* Opens path for reading without blocking on a FIFO; -EINVAL with err
 * for anything but a regular file of a bounded size. */
static int open_file(const char *path, FILE **ret_f, struct stat *ret_st, char *err, size_t err_size)
{
	int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);

	if (fd < 0)
		return fail(-EINVAL, err, err_size, "cannot read '%s': %s", path, strerror(errno));
	if (fstat(fd, ret_st) < 0 || !S_ISREG(ret_st->st_mode)) {
		close(fd);
		return fail(-EINVAL, err, err_size, "'%s' is not a regular file", path);
	}
	if (ret_st->st_size > (off_t)TERRAIN_FILE_MAX_BYTES) {
		close(fd);
		return fail(-EFBIG, err, err_size, "'%s' is %lld bytes, more than %u MiB", path,
			    (long long)ret_st->st_size, TERRAIN_FILE_MAX_BYTES >> 20);
	}
	FILE *f = fdopen(fd, "rb");
	if (!f) {
		close(fd);
		return fail(-ENOMEM, err, err_size, "'%s': out of memory", path);
	}
	*ret_f = f;
	return 0;
}

static uint32_t be32(const uint8_t *b)
{
	return (uint32_t)b[0] << 24 | (uint32_t)b[1] << 16 | (uint32_t)b[2] << 8 | b[3];
}

static int read_file(const char *path, FILE *f, const struct stat *st, struct terrain **ret,
		     char *err, size_t err_size)
{
	uint8_t sig[24] = { 0 };
	size_t n = fread(sig, 1, sizeof(sig), f);
	int r;

	rewind(f);
	if (n >= 8 && png_sig_cmp(sig, 0, 8) == 0) {
		/* The size from the IHDR chunk (always first), before libpng
		 * reads on to the image data. */
		if (n == sizeof(sig) && memcmp(sig + 12, "IHDR", 4) == 0 &&
		    (r = check_size(path, be32(sig + 16), be32(sig + 20), err, err_size)) < 0)
			return r;
		r = read_png(path, f, ret, err, err_size);
	} else if (n >= 13 && memcmp(sig, TERRAIN_RAW_MAGIC " ", 13) == 0)
		r = read_raw(path, f, st->st_size, ret, err, err_size);
	else
		r = fail(-EINVAL, err, err_size, "'%s' is neither a PNG nor a " TERRAIN_RAW_MAGIC " file",
			 path);
	if (r == 0)
		field_finish(*ret);
	return r;
}

/* The cache: the last field read and what its file looked like. */
static struct {
	pthread_mutex_t lock;
	char path[TERRAIN_PATH_MAX];
	dev_t dev;
	ino_t ino;
	off_t size;
	struct timespec mtime;
	struct terrain *t;
} cache = { .lock = PTHREAD_MUTEX_INITIALIZER };

static int same_file(const char *path, const struct stat *st)
{
	return cache.t && strcmp(cache.path, path) == 0 && cache.dev == st->st_dev &&
	       cache.ino == st->st_ino && cache.size == st->st_size &&
	       cache.mtime.tv_sec == st->st_mtim.tv_sec && cache.mtime.tv_nsec == st->st_mtim.tv_nsec;
}

int terrain_load(const char *path, struct terrain **ret, char *err, size_t err_size)
{
	struct stat st;
	FILE *f = NULL;
	struct terrain *t = NULL;
	int r;

	if (!path || !ret)
		return fail(-EINVAL, err, err_size, "no path");
	if ((r = check_path(path, err, err_size)) < 0 ||
	    (r = open_file(path, &f, &st, err, err_size)) < 0)
		return r;
	pthread_mutex_lock(&cache.lock);
	if (same_file(path, &st)) {
		*ret = terrain_ref(cache.t);
		pthread_mutex_unlock(&cache.lock);
		fclose(f);
		return 0;
	}
	pthread_mutex_unlock(&cache.lock);
	r = read_file(path, f, &st, &t, err, err_size);
	fclose(f);
	if (r < 0)
		return r;
	pthread_mutex_lock(&cache.lock);
	terrain_unref(cache.t);
	cache.t = terrain_ref(t);
	snprintf(cache.path, sizeof(cache.path), "%s", path);
	cache.dev = st.st_dev;
	cache.ino = st.st_ino;
	cache.size = st.st_size;
	cache.mtime = st.st_mtim;
	pthread_mutex_unlock(&cache.lock);
	*ret = t;
	return 0;
}
