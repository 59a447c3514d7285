/* dump_exr.c - a table to a single-part scanline EXR and back, through
 * OpenEXR's C core on file I/O of our own. */
#include "dump_internal.h"

#include <assert.h>
#include <errno.h>
#include <fcntl.h>
#include <openexr.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "skymap.h"
#include "skyproto.h"

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
	return dump_fail(err, err_size, exr_errno(io, rv, otherwise), "'%s': %s: %s", path, step,
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
		dump_texel_rgba(t, row * t->width + i, rgba);
		memcpy(out + 16 * (size_t)i, rgba, sizeof(rgba));
	}
}

/* The part's header: the image W x H*D, channels R, G, B, A as FLOAT,
 * ZIP, and the skyd attributes of dump.h; written. */
static exr_result_t exr_write_part_header(exr_context_t ctx, const struct dump_table *t,
					  int *ret_part)
{
	static const char *const channels[] = { "R", "G", "B", "A" };
	exr_result_t rv;
	char text[96];
	int part = 0;

	rv = exr_add_part(ctx, NULL, EXR_STORAGE_SCANLINE, &part);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_initialize_required_attr_simple(ctx, part, (int32_t)t->width,
							 (int32_t)(t->height * t->depth),
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
	*ret_part = part;
	return rv;
}

/* The library's compression, then its output kept only where it is
 * smaller than the chunk's raw bytes. A reader takes a chunk whose size is
 * the raw size for raw data, but OpenEXRCore 3.1 keeps a chunk that
 * compressed to exactly that size compressed: such a chunk read back as
 * noise. Its buffer holds at least the raw bytes (exr_compress_max_buffer_size). */
static exr_result_t exr_compress_or_keep(exr_encode_pipeline_t *enc)
{
	exr_result_t (*compress)(exr_encode_pipeline_t *) = enc->encoding_user_data;
	exr_result_t rv = compress(enc);

	if (rv == EXR_ERR_SUCCESS && enc->compressed_bytes >= enc->packed_bytes &&
	    enc->compressed_buffer != enc->packed_buffer) {
		memcpy(enc->compressed_buffer, enc->packed_buffer, enc->packed_bytes);
		enc->compressed_bytes = enc->packed_bytes;
	}
	return rv;
}

/* Every scanline chunk of t, lines scanlines at a time, staged as float32
 * RGBA in stage (room for lines rows). */
static exr_result_t exr_write_chunks(exr_context_t ctx, int part, const struct dump_table *t,
				     int lines, uint8_t *stage)
{
	exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
	exr_result_t rv = EXR_ERR_SUCCESS;
	size_t row_bytes = 4 * sizeof(float) * t->width;
	uint32_t image_h = t->height * t->depth;
	bool enc_ready = false;

	for (uint32_t y = 0; y < image_h; y += (uint32_t)lines) {
		exr_chunk_info_t cinfo;

		rv = exr_write_scanline_chunk_info(ctx, part, (int)y, &cinfo);
		if (rv != EXR_ERR_SUCCESS)
			break;
		for (int l = 0; l < cinfo.height; l++)
			stage_row(t, dump_scanline_row(t, y + (uint32_t)l), stage + (size_t)l * row_bytes);
		rv = enc_ready ? exr_encoding_update(ctx, part, &cinfo, &enc)
			       : exr_encoding_initialize(ctx, part, &cinfo, &enc);
		if (rv != EXR_ERR_SUCCESS)
			break;
		exr_point_encoder(&enc, t, stage);
		if (!enc_ready) {
			enc_ready = true;
			rv = exr_encoding_choose_default_routines(ctx, part, &enc);
			if (enc.compress_fn) {
				enc.encoding_user_data = (void *)enc.compress_fn;
				enc.compress_fn = exr_compress_or_keep;
			}
		}
		if (rv == EXR_ERR_SUCCESS)
			rv = exr_encoding_run(ctx, part, &enc);
		if (rv != EXR_ERR_SUCCESS)
			break;
	}
	if (enc_ready)
		exr_encoding_destroy(ctx, &enc);
	return rv;
}

int dump_exr(const char *path, const struct dump_table *t, char *err, size_t err_size)
{
	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	struct exr_io io = { .fd = -1 };
	struct dump_out out;
	exr_context_t ctx = NULL;
	exr_result_t rv = EXR_ERR_SUCCESS;
	uint8_t *stage = NULL;
	const char *step;
	int part = 0, lines = 0, r;

	if ((r = dump_table_check(t, err, err_size)) < 0)
		return r;
	if (!path)
		return dump_fail(err, err_size, -EINVAL, "dump: no path");

	if ((r = dump_out_open(&out, path, err, err_size)) < 0)
		return r;
	io.fd = out.fd;

	init.error_handler_fn = exr_on_error;
	init.user_data = &io;
	init.write_fn = exr_write_fn;
	step = "create";
	rv = exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_write_part_header(ctx, t, &part);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_get_scanlines_per_chunk(ctx, part, &lines);
	if (rv != EXR_ERR_SUCCESS)
		goto exr_failed;
	assert(lines > 0);
	stage = malloc((size_t)lines * 4 * sizeof(float) * t->width);
	if (!stage) {
		r = dump_fail(err, err_size, -ENOMEM, "'%s': out of memory", path);
		goto out;
	}

	step = "write";
	rv = exr_write_chunks(ctx, part, t, lines, stage);
	if (rv != EXR_ERR_SUCCESS)
		goto exr_failed;
	/* finish writes the chunk offset table: it can fail too. */
	step = "finish";
	rv = exr_finish(&ctx);
	ctx = NULL;
	if (rv != EXR_ERR_SUCCESS)
		goto exr_failed;
	r = close(out.fd);
	out.fd = -1;
	if (r < 0)
		r = dump_fail(err, err_size, -errno, "'%s': close: %s", path, strerror(errno));
	else
		r = dump_out_commit(&out, path, err, err_size);
	goto out;

exr_failed:
	r = exr_fail(&io, rv, EIO, path, step, err, err_size);
out:
	if (ctx)
		exr_finish(&ctx);
	free(stage);
	if (r < 0)
		dump_out_abort(&out);
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

/* The table's shape from the data window dw and the skyd attributes, into
 * *info and *shape (float32; texels set to something non-NULL, as only the
 * shape is checked); -EBADMSG (and err) where they disagree or make no
 * table. */
static int exr_read_shape(exr_context_t ctx, const exr_attr_box2i_t *dw, int lines,
			  const char *path, struct dump_exr_info *info, struct dump_table *shape,
			  char *err, size_t err_size)
{
	uint64_t w = (uint64_t)((int64_t)dw->max.x - dw->min.x + 1);
	uint64_t h = (uint64_t)((int64_t)dw->max.y - dw->min.y + 1);
	uint64_t size[3] = { w, h, 1 };
	const char *s;
	int32_t len;

	if (exr_attr_get_string(ctx, 0, "skyd:table", &len, &s) == EXR_ERR_SUCCESS)
		snprintf(info->name, sizeof(info->name), "%.*s", (int)len, s);
	if (exr_attr_get_string(ctx, 0, "skyd:size", &len, &s) == EXR_ERR_SUCCESS) {
		char text[64];
		uint32_t v[3];

		snprintf(text, sizeof(text), "%.*s", (int)len, s);
		if (!parse_size(text, v) || v[0] != w || (uint64_t)v[1] * v[2] != h)
			return dump_fail(err, err_size, -EBADMSG,
					 "'%s': skyd:size '%s' does not match %llux%llu", path, text,
					 (unsigned long long)w, (unsigned long long)h);
		size[1] = v[1], size[2] = v[2];
	}
	if (exr_attr_get_string(ctx, 0, "skyd:uv_mapping", &len, &s) == EXR_ERR_SUCCESS) {
		char text[16];

		snprintf(text, sizeof(text), "%.*s", (int)len, s);
		info->uv_mapping_version = (uint32_t)strtoul(text, NULL, 10);
	}

	shape->name = info->name;
	shape->texels = path;
	shape->format = SKY_FORMAT_RGBA32F;
	shape->width = (uint32_t)size[0], shape->height = (uint32_t)size[1];
	shape->depth = (uint32_t)size[2];
	if (w > UINT32_MAX || h > UINT32_MAX || dump_table_check(shape, NULL, 0) < 0 || lines <= 0)
		return dump_fail(err, err_size, -EBADMSG, "'%s': bad image size", path);
	info->width = shape->width, info->height = shape->height, info->depth = shape->depth;
	return 0;
}

/* Every scanline chunk, lines scanlines at a time through stage (room for
 * lines rows of float RGBA), into texels in table order. */
static exr_result_t exr_read_chunks(exr_context_t ctx, const exr_attr_box2i_t *dw,
				    const struct dump_table *shape, int lines, float *texels,
				    float *stage)
{
	exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
	exr_result_t rv = EXR_ERR_SUCCESS;
	uint32_t w = shape->width, h = shape->height * shape->depth;
	size_t row_floats = 4 * (size_t)w;
	bool dec_ready = false;

	for (uint32_t y = 0; y < h; y += (uint32_t)lines) {
		exr_chunk_info_t cinfo;

		rv = exr_read_scanline_chunk_info(ctx, 0, dw->min.y + (int)y, &cinfo);
		if (rv != EXR_ERR_SUCCESS)
			break;
		rv = dec_ready ? exr_decoding_update(ctx, 0, &cinfo, &dec)
			       : exr_decoding_initialize(ctx, 0, &cinfo, &dec);
		if (rv != EXR_ERR_SUCCESS)
			break;
		exr_point_decoder(&dec, stage, w);
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
			break;
		for (int l = 0; l < cinfo.height; l++)
			memcpy(texels + dump_scanline_row(shape, y + (uint32_t)l) * row_floats,
			       stage + (size_t)l * row_floats, row_floats * sizeof(float));
	}
	if (dec_ready)
		exr_decoding_destroy(ctx, &dec);
	return rv;
}

int dump_read_exr(const char *path, struct dump_exr_info *ret_info, float **ret_texels,
		  char *err, size_t err_size)
{
	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	struct exr_io io = { .fd = -1 };
	struct dump_exr_info info = { 0 };
	struct dump_table shape = { 0 };
	exr_context_t ctx = NULL;
	exr_result_t rv = EXR_ERR_SUCCESS;
	exr_storage_t storage;
	exr_attr_box2i_t dw;
	float *texels = NULL, *stage = NULL;
	const char *step = "open";
	int count = 0, lines = 0, r = 0;
	size_t row_floats;

	if (!path || !ret_info || !ret_texels)
		return dump_fail(err, err_size, -EINVAL, "dump: read: bad arguments");
	io.fd = open(path, O_RDONLY | O_CLOEXEC | O_NOCTTY);
	if (io.fd < 0)
		return dump_fail(err, err_size, -errno, "'%s': %s", path, strerror(errno));

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
		r = dump_fail(err, err_size, -ENOTSUP, "'%s': not a single-part scanline image", path);
		goto out;
	}
	if ((r = exr_read_shape(ctx, &dw, lines, path, &info, &shape, err, err_size)) < 0)
		goto out;
	row_floats = 4 * (size_t)shape.width;
	texels = malloc(row_floats * shape.height * shape.depth * sizeof(float));
	stage = malloc(row_floats * (size_t)lines * sizeof(float));
	if (!texels || !stage) {
		r = dump_fail(err, err_size, -ENOMEM, "'%s': out of memory", path);
		goto out;
	}

	step = "read";
	rv = exr_read_chunks(ctx, &dw, &shape, lines, texels, stage);
	if (rv != EXR_ERR_SUCCESS)
		goto exr_failed;
	*ret_info = info;
	*ret_texels = texels;
	texels = NULL;
	goto out;

exr_failed:
	r = exr_fail(&io, rv, EBADMSG, path, step, err, err_size);
out:
	if (ctx)
		exr_finish(&ctx);
	if (io.fd >= 0)
		close(io.fd);
	free(stage);
	free(texels);
	return r;
}
