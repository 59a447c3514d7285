/* dump.c - sky tables to EXR (OpenEXR's C core), PNG previews (libpng) and
 * JSON manifests, and EXR back to tables. */
#include "dump.h"

#include <assert.h>
#include <errno.h>
#include <fcntl.h>
#include <locale.h>
#include <math.h>
#include <openexr.h>
#include <png.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include "skymap.h"
#include "skyproto.h"

static int fail(char *err, size_t err_size, int r, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));

static int fail(char *err, size_t err_size, int r, const char *fmt, ...)
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
static int table_check(const struct dump_table *t, char *err, size_t err_size)
{
	if (!t || !t->name || !t->texels)
		return fail(err, err_size, -EINVAL, "dump: no table");
	if (!texel_bytes(t->format))
		return fail(err, err_size, -EINVAL, "dump: table '%s': unknown format %u",
			    t->name, t->format);
	if (!t->width || !t->height || !t->depth || t->width > INT32_MAX ||
	    (uint64_t)t->height * t->depth > INT32_MAX ||
	    (uint64_t)t->width * t->height * t->depth > SIZE_MAX / 16)
		return fail(err, err_size, -EINVAL, "dump: table '%s': bad size %ux%ux%u",
			    t->name, t->width, t->height, t->depth);
	return 0;
}

/* Table row of image scanline y, as documented in dump.h. */
static size_t scanline_row(const struct dump_table *t, uint32_t y)
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

static void texel_rgba(const struct dump_table *t, size_t index, float ret[4])
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

/* A file is written under a temporary name beside its final one and renamed
 * over it only when complete: a reader of the dump directory never sees half
 * a file, and a failed write leaves what was there before. */
struct out_file {
	char tmp[4096];
	int fd;
};

static int out_open(struct out_file *o, const char *path, char *err, size_t err_size)
{
	o->fd = -1;
	for (int attempt = 0; attempt < 16; attempt++) {
		uint32_t salt = 0;

		if (getrandom(&salt, sizeof(salt), GRND_NONBLOCK) < 0)
			salt = (uint32_t)getpid() * 2654435761u + (uint32_t)attempt;
		if ((size_t)snprintf(o->tmp, sizeof(o->tmp), "%s.tmp-%08x", path, salt) >= sizeof(o->tmp))
			return fail(err, err_size, -ENAMETOOLONG, "'%s': %s", path, strerror(ENAMETOOLONG));
		o->fd = open(o->tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOCTTY, 0644);
		if (o->fd >= 0)
			return 0;
		if (errno != EEXIST)
			break;
	}
	return fail(err, err_size, -errno, "'%s': %s", path, strerror(errno));
}

/* The caller has closed o->fd (and checked that). */
static int out_commit(struct out_file *o, const char *path, char *err, size_t err_size)
{
	assert(o->fd < 0);
	if (rename(o->tmp, path) == 0)
		return 0;
	int r = fail(err, err_size, -errno, "'%s': rename: %s", path, strerror(errno));
	unlink(o->tmp);
	return r;
}

static void out_abort(struct out_file *o)
{
	if (o->fd >= 0)
		close(o->fd);
	o->fd = -1;
	unlink(o->tmp);
}

/* EXR ------------------------------------------------------------------- */

/* Our own file I/O under the C core, so that the fd is CLOEXEC, errno
 * survives to the caller and the library's messages land in err instead of
 * on stderr. */
struct exr_io {
	int fd;
	int saved_errno;
	char msg[200];		/* the library's first message */
};

static void exr_on_error(exr_const_context_t ctx, exr_result_t code, const char *msg)
{
	void *user = NULL;
	struct exr_io *io;

	if (exr_get_user_data(ctx, &user) != EXR_ERR_SUCCESS || !user)
		return;
	io = user;
	if (!io->msg[0])
		snprintf(io->msg, sizeof(io->msg), "%s", msg ? msg : exr_get_default_error_message(code));
}

static int64_t exr_write_fn(exr_const_context_t ctx, void *user, const void *buf, uint64_t size,
			    uint64_t offset, exr_stream_error_func_ptr_t error_cb)
{
	struct exr_io *io = user;
	uint64_t done = 0;

	while (done < size) {
		ssize_t n = pwrite(io->fd, (const char *)buf + done, size - done, (off_t)(offset + done));
		if (n < 0 && errno == EINTR)
			continue;
		if (n <= 0) {
			io->saved_errno = n < 0 ? errno : EIO;
			error_cb(ctx, EXR_ERR_WRITE_IO, "%s", strerror(io->saved_errno));
			return -1;
		}
		done += (uint64_t)n;
	}
	return (int64_t)done;
}

/* Short reads at the end of the file are the library's to judge. */
static int64_t exr_read_fn(exr_const_context_t ctx, void *user, void *buf, uint64_t size,
			   uint64_t offset, exr_stream_error_func_ptr_t error_cb)
{
	struct exr_io *io = user;
	uint64_t done = 0;

	while (done < size) {
		ssize_t n = pread(io->fd, (char *)buf + done, size - done, (off_t)(offset + done));
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0) {
			io->saved_errno = errno;
			error_cb(ctx, EXR_ERR_READ_IO, "read: %s", strerror(errno));
			return -1;
		}
		if (n == 0)
			break;
		done += (uint64_t)n;
	}
	return (int64_t)done;
}

static int64_t exr_size_fn(exr_const_context_t ctx, void *user)
{
	struct exr_io *io = user;
	struct stat st;

	return fstat(io->fd, &st) == 0 ? (int64_t)st.st_size : -1;
}

/* Errno for a failed library call: the I/O's own if it failed, otherwise
 * what the caller says a library failure means here. */
static int exr_errno(const struct exr_io *io, exr_result_t rv, int otherwise)
{
	if (io->saved_errno)
		return -io->saved_errno;
	return rv == EXR_ERR_OUT_OF_MEMORY ? -ENOMEM : -otherwise;
}

static int exr_fail(const struct exr_io *io, exr_result_t rv, int otherwise, const char *path,
		    const char *step, char *err, size_t err_size)
{
	return fail(err, err_size, exr_errno(io, rv, otherwise), "'%s': %s: %s", path, step,
		    io->msg[0] ? io->msg : exr_get_default_error_message(rv));
}

/* The channel of a pipeline: byte offset in an RGBA texel, -1 if none. */
static int channel_offset(const char *name, size_t component_bytes)
{
	static const char rgba[] = "RGBA";
	const char *p = name && name[0] && !name[1] ? strchr(rgba, name[0]) : NULL;
	return p ? (int)((size_t)(p - rgba) * component_bytes) : -1;
}

/* Fill the encoder's channels from stage, which holds the chunk's scanlines
 * contiguously as float32 RGBA. */
static void exr_point_encoder(exr_encode_pipeline_t *enc, const struct dump_table *t,
			      const uint8_t *stage)
{
	for (int c = 0; c < enc->channel_count; c++) {
		exr_coding_channel_info_t *ch = &enc->channels[c];
		int off = channel_offset(ch->channel_name, sizeof(float));
		assert(off >= 0);	/* we declared exactly R, G, B, A */
		ch->user_data_type = EXR_PIXEL_FLOAT;
		ch->user_bytes_per_element = sizeof(float);
		ch->user_pixel_stride = 4 * sizeof(float);
		ch->user_line_stride = (int32_t)(4 * sizeof(float) * t->width);
		ch->encode_from_ptr = stage + off;
	}
}

/* Table row row as float32 RGBA values into out: a float32 table's bytes,
 * a binary16 one's widened and scaled (texel_rgba). */
static void stage_row(const struct dump_table *t, size_t row, uint8_t *out)
{
	if (t->format == SKY_FORMAT_RGBA32F) {
		memcpy(out, (const uint8_t *)t->texels + row * 16 * t->width, 16 * (size_t)t->width);
		return;
	}
	for (uint32_t i = 0; i < t->width; i++) {
		float rgba[4];
		texel_rgba(t, row * t->width + i, rgba);
		memcpy(out + 16 * (size_t)i, rgba, sizeof(rgba));
	}
}

int dump_exr(const char *path, const struct dump_table *t, char *err, size_t err_size)
{
	static const char *const channels[] = { "R", "G", "B", "A" };
	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
	struct exr_io io = { .fd = -1 };
	struct out_file out;
	exr_context_t ctx = NULL;
	exr_result_t rv = EXR_ERR_SUCCESS;
	uint8_t *stage = NULL;
	bool enc_ready = false;
	const char *step;
	char text[96];
	int part = 0, lines = 0, r;
	uint32_t image_h;
	size_t row_bytes;

	if ((r = table_check(t, err, err_size)) < 0)
		return r;
	if (!path)
		return fail(err, err_size, -EINVAL, "dump: no path");
	row_bytes = 4 * sizeof(float) * t->width;
	image_h = t->height * t->depth;

	if ((r = out_open(&out, path, err, err_size)) < 0)
		return r;
	io.fd = out.fd;

	init.error_handler_fn = exr_on_error;
	init.user_data = &io;
	init.write_fn = exr_write_fn;
	step = "create";
	rv = exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_add_part(ctx, NULL, EXR_STORAGE_SCANLINE, &part);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_initialize_required_attr_simple(ctx, part, (int32_t)t->width, (int32_t)image_h,
							 EXR_COMPRESSION_ZIP);
	for (int c = 0; c < 4 && rv == EXR_ERR_SUCCESS; c++)
		rv = exr_add_channel(ctx, part, channels[c], EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LINEAR, 1, 1);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_attr_set_string(ctx, part, "skyd:table", t->name);
	if (rv == EXR_ERR_SUCCESS) {
		snprintf(text, sizeof(text), "%ux%ux%u", t->width, t->height, t->depth);
		rv = exr_attr_set_string(ctx, part, "skyd:size", text);
	}
	if (rv == EXR_ERR_SUCCESS) {
		snprintf(text, sizeof(text), "%u", (unsigned)SKYMAP_VERSION);
		rv = exr_attr_set_string(ctx, part, "skyd:uv_mapping", text);
	}
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_attr_set_string(ctx, part, "skyd:layout",
					 "slice k in scanlines [k*H, (k+1)*H), top first; "
					 "scanline k*H + H-1-j holds row j (v up)");
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_write_header(ctx);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_get_scanlines_per_chunk(ctx, part, &lines);
	if (rv != EXR_ERR_SUCCESS)
		goto exr_failed;
	assert(lines > 0);
	stage = malloc((size_t)lines * row_bytes);
	if (!stage) {
		r = fail(err, err_size, -ENOMEM, "'%s': out of memory", path);
		goto out;
	}

	step = "write";
	for (uint32_t y = 0; y < image_h; y += (uint32_t)lines) {
		exr_chunk_info_t cinfo;

		rv = exr_write_scanline_chunk_info(ctx, part, (int)y, &cinfo);
		if (rv != EXR_ERR_SUCCESS)
			goto exr_failed;
		for (int l = 0; l < cinfo.height; l++)
			stage_row(t, scanline_row(t, y + (uint32_t)l), stage + (size_t)l * row_bytes);
		rv = enc_ready ? exr_encoding_update(ctx, part, &cinfo, &enc)
			       : exr_encoding_initialize(ctx, part, &cinfo, &enc);
		if (rv != EXR_ERR_SUCCESS)
			goto exr_failed;
		exr_point_encoder(&enc, t, stage);
		if (!enc_ready) {
			enc_ready = true;
			rv = exr_encoding_choose_default_routines(ctx, part, &enc);
		}
		if (rv == EXR_ERR_SUCCESS)
			rv = exr_encoding_run(ctx, part, &enc);
		if (rv != EXR_ERR_SUCCESS)
			goto exr_failed;
	}
	if (enc_ready) {
		exr_encoding_destroy(ctx, &enc);
		enc_ready = false;
	}
	/* finish writes the chunk offset table: it can fail too. */
	step = "finish";
	rv = exr_finish(&ctx);
	ctx = NULL;
	if (rv != EXR_ERR_SUCCESS)
		goto exr_failed;
	r = close(out.fd);
	out.fd = -1;
	if (r < 0)
		r = fail(err, err_size, -errno, "'%s': close: %s", path, strerror(errno));
	else
		r = out_commit(&out, path, err, err_size);
	goto out;

exr_failed:
	r = exr_fail(&io, rv, EIO, path, step, err, err_size);
out:
	if (enc_ready)
		exr_encoding_destroy(ctx, &enc);
	if (ctx)
		exr_finish(&ctx);
	free(stage);
	if (r < 0)
		out_abort(&out);
	return r;
}

/* skyd:size, strictly "WxHxD" of positive decimals. */
static bool parse_size(const char *s, uint32_t v[3])
{
	for (int n = 0; n < 3; n++) {
		char *end;
		unsigned long x;

		if (*s < '1' || *s > '9')
			return false;
		errno = 0;
		x = strtoul(s, &end, 10);
		if (errno || x > UINT32_MAX || *end != (n < 2 ? 'x' : '\0'))
			return false;
		v[n] = (uint32_t)x;
		s = end + (n < 2);
	}
	return true;
}

/* Point the decoder's channels into stage (float RGBA, contiguous lines). */
static void exr_point_decoder(exr_decode_pipeline_t *dec, float *stage, uint32_t width)
{
	for (int c = 0; c < dec->channel_count; c++) {
		exr_coding_channel_info_t *ch = &dec->channels[c];
		int off = channel_offset(ch->channel_name, sizeof(float));

		ch->decode_to_ptr = off < 0 ? NULL : (uint8_t *)stage + off;
		ch->user_data_type = EXR_PIXEL_FLOAT;
		ch->user_bytes_per_element = sizeof(float);
		ch->user_pixel_stride = 4 * sizeof(float);
		ch->user_line_stride = (int32_t)(4 * sizeof(float) * width);
	}
}

int dump_read_exr(const char *path, struct dump_exr_info *ret_info, float **ret_texels,
		  char *err, size_t err_size)
{
	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
	struct exr_io io = { .fd = -1 };
	struct dump_exr_info info = { 0 };
	struct dump_table shape = { 0 };
	exr_context_t ctx = NULL;
	exr_result_t rv = EXR_ERR_SUCCESS;
	exr_storage_t storage;
	exr_attr_box2i_t dw;
	float *texels = NULL, *stage = NULL;
	bool dec_ready = false;
	const char *s, *step = "open";
	int count = 0, lines = 0, r = 0;
	int32_t len;
	uint64_t w, h, size[3];
	size_t row_floats;

	if (!path || !ret_info || !ret_texels)
		return fail(err, err_size, -EINVAL, "dump: read: bad arguments");
	io.fd = open(path, O_RDONLY | O_CLOEXEC | O_NOCTTY);
	if (io.fd < 0)
		return fail(err, err_size, -errno, "'%s': %s", path, strerror(errno));

	init.error_handler_fn = exr_on_error;
	init.user_data = &io;
	init.read_fn = exr_read_fn;
	init.size_fn = exr_size_fn;
	rv = exr_start_read(&ctx, path, &init);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_get_count(ctx, &count);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_get_storage(ctx, 0, &storage);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_get_data_window(ctx, 0, &dw);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_get_scanlines_per_chunk(ctx, 0, &lines);
	if (rv != EXR_ERR_SUCCESS)
		goto exr_failed;
	if (count != 1 || storage != EXR_STORAGE_SCANLINE) {
		r = fail(err, err_size, -ENOTSUP, "'%s': not a single-part scanline image", path);
		goto out;
	}
	w = (uint64_t)((int64_t)dw.max.x - dw.min.x + 1);
	h = (uint64_t)((int64_t)dw.max.y - dw.min.y + 1);
	size[0] = w, size[1] = h, size[2] = 1;

	if (exr_attr_get_string(ctx, 0, "skyd:table", &len, &s) == EXR_ERR_SUCCESS)
		snprintf(info.name, sizeof(info.name), "%.*s", (int)len, s);
	if (exr_attr_get_string(ctx, 0, "skyd:size", &len, &s) == EXR_ERR_SUCCESS) {
		char text[64];
		uint32_t v[3];

		snprintf(text, sizeof(text), "%.*s", (int)len, s);
		if (!parse_size(text, v) || v[0] != w || (uint64_t)v[1] * v[2] != h) {
			r = fail(err, err_size, -EBADMSG, "'%s': skyd:size '%s' does not match %llux%llu",
				 path, text, (unsigned long long)w, (unsigned long long)h);
			goto out;
		}
		size[1] = v[1], size[2] = v[2];
	}
	if (exr_attr_get_string(ctx, 0, "skyd:uv_mapping", &len, &s) == EXR_ERR_SUCCESS) {
		char text[16];

		snprintf(text, sizeof(text), "%.*s", (int)len, s);
		info.uv_mapping_version = (uint32_t)strtoul(text, NULL, 10);
	}

	shape.name = info.name;
	shape.texels = path;	/* any non-NULL: only the shape is checked */
	shape.format = SKY_FORMAT_RGBA32F;
	shape.width = (uint32_t)size[0], shape.height = (uint32_t)size[1], shape.depth = (uint32_t)size[2];
	if (w > UINT32_MAX || h > UINT32_MAX || table_check(&shape, NULL, 0) < 0 || lines <= 0) {
		r = fail(err, err_size, -EBADMSG, "'%s': bad image size", path);
		goto out;
	}
	info.width = shape.width, info.height = shape.height, info.depth = shape.depth;
	row_floats = 4 * (size_t)w;
	texels = malloc(row_floats * h * sizeof(float));
	stage = malloc(row_floats * (size_t)lines * sizeof(float));
	if (!texels || !stage) {
		r = fail(err, err_size, -ENOMEM, "'%s': out of memory", path);
		goto out;
	}

	step = "read";
	for (uint32_t y = 0; y < h; y += (uint32_t)lines) {
		exr_chunk_info_t cinfo;

		rv = exr_read_scanline_chunk_info(ctx, 0, dw.min.y + (int)y, &cinfo);
		if (rv != EXR_ERR_SUCCESS)
			goto exr_failed;
		rv = dec_ready ? exr_decoding_update(ctx, 0, &cinfo, &dec)
			       : exr_decoding_initialize(ctx, 0, &cinfo, &dec);
		if (rv != EXR_ERR_SUCCESS)
			goto exr_failed;
		exr_point_decoder(&dec, stage, (uint32_t)w);
		if (!dec_ready) {
			dec_ready = true;
			rv = exr_decoding_choose_default_routines(ctx, 0, &dec);
		}
		/* Channels the file lacks keep these. */
		for (size_t i = 0; i < row_floats * (size_t)cinfo.height; i++)
			stage[i] = i % 4 == 3 ? 1.0f : 0.0f;
		if (rv == EXR_ERR_SUCCESS)
			rv = exr_decoding_run(ctx, 0, &dec);
		if (rv != EXR_ERR_SUCCESS)
			goto exr_failed;
		for (int l = 0; l < cinfo.height; l++)
			memcpy(texels + scanline_row(&shape, y + (uint32_t)l) * row_floats,
			       stage + (size_t)l * row_floats, row_floats * sizeof(float));
	}
	*ret_info = info;
	*ret_texels = texels;
	texels = NULL;
	goto out;

exr_failed:
	r = exr_fail(&io, rv, EBADMSG, path, step, err, err_size);
out:
	if (dec_ready)
		exr_decoding_destroy(ctx, &dec);
	if (ctx)
		exr_finish(&ctx);
	if (io.fd >= 0)
		close(io.fd);
	free(stage);
	free(texels);
	return r;
}

/* PNG ------------------------------------------------------------------- */

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

	if (table_check(t, NULL, 0) < 0 || !ret_exposure)
		return -EINVAL;
	n = (size_t)t->width * t->height * t->depth;
	lum = malloc(n * sizeof(float));
	if (!lum)
		return -ENOMEM;
	for (size_t i = 0; i < n; i++) {
		texel_rgba(t, i, rgba);
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

/* All the libpng calls that may longjmp, kept apart so that no local of the
 * caller lives across setjmp. */
static int png_encode(png_structp png, png_infop info, FILE *f, const struct dump_table *t,
		      double exposure, enum dump_curve curve, uint8_t *row)
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
		size_t base = scanline_row(t, y) * t->width;
		for (uint32_t i = 0; i < t->width; i++) {
			texel_rgba(t, base + i, rgba);
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
	double exposure = opt ? opt->exposure : 0.0;
	struct png_err pe = { .msg = "" };
	struct out_file out;
	png_structp png = NULL;
	png_infop info = NULL;
	uint8_t *row = NULL;
	FILE *f = NULL;
	int r;

	if ((r = table_check(t, err, err_size)) < 0)
		return r;
	if (!path || (curve != DUMP_CURVE_ACES && curve != DUMP_CURVE_REINHARD) || !isfinite(exposure))
		return fail(err, err_size, -EINVAL, "dump: '%s': bad path or tone mapping", t->name);
	if (!(exposure > 0.0) && (r = dump_auto_exposure(t, &exposure)) < 0)
		return fail(err, err_size, r, "'%s': exposure: %s", path, strerror(-r));

	if ((r = out_open(&out, path, err, err_size)) < 0)
		return r;
	f = fdopen(out.fd, "wb");
	if (!f) {
		r = fail(err, err_size, -errno, "'%s': %s", path, strerror(errno));
		goto out;
	}
	out.fd = -1;	/* f owns it */
	row = malloc(3 * (size_t)t->width);
	png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &pe, png_on_error, png_on_warning);
	info = png ? png_create_info_struct(png) : NULL;
	if (!row || !info) {
		r = fail(err, err_size, -ENOMEM, "'%s': out of memory", path);
		goto out;
	}
	errno = 0;	/* so that png_on_error sees only a write's errno */
	if (png_encode(png, info, f, t, exposure, curve, row) < 0) {
		r = fail(err, err_size, pe.saved_errno ? -pe.saved_errno : -EIO, "'%s': png: %s%s%s%s",
			 path, pe.msg, pe.saved_errno ? " (" : "",
			 pe.saved_errno ? strerror(pe.saved_errno) : "", pe.saved_errno ? ")" : "");
		goto out;
	}
out:
	png_destroy_write_struct(&png, &info);
	if (f && fclose(f) != 0 && r == 0)
		r = fail(err, err_size, -errno, "'%s': %s", path, strerror(errno));
	free(row);
	if (r == 0)
		r = out_commit(&out, path, err, err_size);
	if (r < 0)
		out_abort(&out);
	return r;
}

/* JSON ------------------------------------------------------------------ */

#define JSON_DEPTH_MAX 32

struct dump_json {
	FILE *f;			/* NULL: the buffer */
	char *buf;
	size_t len, cap;
	locale_t c_locale;
	int error;			/* sticky, 0 or -errno */
	int depth;			/* open containers */
	char kind[JSON_DEPTH_MAX + 1];	/* '{' or '[' per level, 1-based */
	uint32_t items[JSON_DEPTH_MAX + 1];
	bool after_key;			/* a key waits for its value */
	bool top_done;
};

static struct dump_json *json_new(FILE *f)
{
	struct dump_json *j = calloc(1, sizeof(*j));

	if (!j)
		return NULL;
	j->f = f;
	j->c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	if (!j->c_locale || (!f && !(j->buf = calloc(1, j->cap = 256)))) {
		dump_json_free(j);
		return NULL;
	}
	return j;
}

struct dump_json *dump_json_new_file(FILE *f)
{
	return f ? json_new(f) : NULL;
}

struct dump_json *dump_json_new_buffer(void)
{
	return json_new(NULL);
}

void dump_json_free(struct dump_json *j)
{
	if (!j)
		return;
	if (j->c_locale)
		freelocale(j->c_locale);
	free(j->buf);
	free(j);
}

static int json_error(struct dump_json *j, int r)
{
	if (!j->error)
		j->error = r;
	return j->error;
}

static void json_put(struct dump_json *j, const char *s, size_t n)
{
	if (j->error)
		return;
	if (j->f) {
		if (fwrite(s, 1, n, j->f) != n)
			json_error(j, -EIO);
		return;
	}
	if (j->cap - j->len <= n) {
		size_t cap = j->cap;
		char *p;

		while (cap - j->len <= n) {
			if (cap > SIZE_MAX / 2) {
				json_error(j, -ENOMEM);
				return;
			}
			cap *= 2;
		}
		if (!(p = realloc(j->buf, cap))) {
			json_error(j, -ENOMEM);
			return;
		}
		j->buf = p;
		j->cap = cap;
	}
	memcpy(j->buf + j->len, s, n);
	j->len += n;
	j->buf[j->len] = '\0';
}

static void json_puts(struct dump_json *j, const char *s)
{
	json_put(j, s, strlen(s));
}

static void json_newline(struct dump_json *j)
{
	json_put(j, "\n", 1);
	for (int d = 0; d < j->depth; d++)
		json_put(j, "  ", 2);
}

/* Separator and indent before a value; refuses a value where none fits. */
static int json_before_value(struct dump_json *j)
{
	if (j->error)
		return j->error;
	if (j->depth == 0)
		return j->top_done ? json_error(j, -EINVAL) : 0;
	if (j->kind[j->depth] == '{') {
		if (!j->after_key)
			return json_error(j, -EINVAL);
		j->after_key = false;
		return 0;
	}
	if (j->items[j->depth]++)
		json_put(j, ",", 1);
	json_newline(j);
	return j->error;
}

static int json_after_value(struct dump_json *j)
{
	if (j->depth == 0)
		j->top_done = true;
	return j->error;
}

static void json_put_string(struct dump_json *j, const char *s)
{
	json_put(j, "\"", 1);
	for (const char *run = s;; s++) {
		unsigned char c = (unsigned char)*s;
		char esc[8];

		if (c >= 0x20 && c != '"' && c != '\\')
			continue;
		json_put(j, run, (size_t)(s - run));
		if (!c)
			break;
		switch (c) {
		case '"': json_puts(j, "\\\""); break;
		case '\\': json_puts(j, "\\\\"); break;
		case '\b': json_puts(j, "\\b"); break;
		case '\f': json_puts(j, "\\f"); break;
		case '\n': json_puts(j, "\\n"); break;
		case '\r': json_puts(j, "\\r"); break;
		case '\t': json_puts(j, "\\t"); break;
		default:
			snprintf(esc, sizeof(esc), "\\u%04x", c);
			json_puts(j, esc);
		}
		run = s + 1;
	}
	json_put(j, "\"", 1);
}

static int json_begin(struct dump_json *j, char kind)
{
	if (!j)
		return -EINVAL;
	if (json_before_value(j) < 0)
		return j->error;
	if (j->depth == JSON_DEPTH_MAX)
		return json_error(j, -EINVAL);
	json_put(j, &kind, 1);
	j->depth++;
	j->kind[j->depth] = kind;
	j->items[j->depth] = 0;
	return j->error;
}

static int json_end(struct dump_json *j, char kind)
{
	if (!j)
		return -EINVAL;
	if (j->error)
		return j->error;
	if (j->depth == 0 || j->kind[j->depth] != kind || j->after_key)
		return json_error(j, -EINVAL);
	j->depth--;
	if (j->items[j->depth + 1])
		json_newline(j);
	json_put(j, kind == '{' ? "}" : "]", 1);
	return json_after_value(j);
}

int dump_json_begin_object(struct dump_json *j)
{
	return json_begin(j, '{');
}

int dump_json_end_object(struct dump_json *j)
{
	return json_end(j, '{');
}

int dump_json_begin_array(struct dump_json *j)
{
	return json_begin(j, '[');
}

int dump_json_end_array(struct dump_json *j)
{
	return json_end(j, '[');
}

int dump_json_key(struct dump_json *j, const char *key)
{
	if (!j)
		return -EINVAL;
	if (j->error)
		return j->error;
	if (!key || j->depth == 0 || j->kind[j->depth] != '{' || j->after_key)
		return json_error(j, -EINVAL);
	if (j->items[j->depth]++)
		json_put(j, ",", 1);
	json_newline(j);
	json_put_string(j, key);
	json_put(j, ": ", 2);
	j->after_key = true;
	return j->error;
}

/* A scalar already formatted; NULL text is a misuse. */
static int json_scalar(struct dump_json *j, const char *text)
{
	if (!j)
		return -EINVAL;
	if (!text)
		return json_error(j, -EINVAL);
	if (json_before_value(j) < 0)
		return j->error;
	json_puts(j, text);
	return json_after_value(j);
}

int dump_json_string(struct dump_json *j, const char *s)
{
	if (!j)
		return -EINVAL;
	if (!s)
		return json_error(j, -EINVAL);
	if (json_before_value(j) < 0)
		return j->error;
	json_put_string(j, s);
	return json_after_value(j);
}

int dump_json_number(struct dump_json *j, double x)
{
	char text[32];
	locale_t old;

	if (!j)
		return -EINVAL;
	if (!isfinite(x))
		return json_scalar(j, "null");
	old = uselocale(j->c_locale);
	snprintf(text, sizeof(text), "%.17g", x);
	uselocale(old);
	return json_scalar(j, text);
}

int dump_json_uint(struct dump_json *j, uint64_t x)
{
	char text[24];

	snprintf(text, sizeof(text), "%llu", (unsigned long long)x);
	return json_scalar(j, text);
}

int dump_json_bool(struct dump_json *j, bool b)
{
	return json_scalar(j, b ? "true" : "false");
}

int dump_json_null(struct dump_json *j)
{
	return json_scalar(j, "null");
}

int dump_json_finish(struct dump_json *j)
{
	if (!j)
		return -EINVAL;
	if (j->error)
		return j->error;
	if (j->depth != 0 || !j->top_done)
		return json_error(j, -EINVAL);
	json_put(j, "\n", 1);
	if (j->f && fflush(j->f) != 0)
		json_error(j, -errno);
	return j->error;
}

const char *dump_json_buffer(const struct dump_json *j, size_t *ret_len)
{
	if (!j || j->f)
		return NULL;
	if (ret_len)
		*ret_len = j->len;
	return j->buf;
}
