/* dump_internal.h - what the files of dump/ share (dump.c): not part of
 * dump.h's API. */
#ifndef SKYD_DUMP_INTERNAL_H
#define SKYD_DUMP_INTERNAL_H

#include "dump.h"

/* Writes the message to err (if err and err_size) and returns r. */
int dump_fail(char *err, size_t err_size, int r, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));

/* 0, or -EINVAL (and err) for a table no writer can take: NULL parts, an
 * unknown format, a size that overflows EXR's and PNG's int32 coordinates
 * or the texel count. */
int dump_table_check(const struct dump_table *t, char *err, size_t err_size);

/* Table row of image scanline y, as documented in dump.h. */
size_t dump_scanline_row(const struct dump_table *t, uint32_t y);

/* Texel index of a checked table as float RGBA: float32 as stored, binary16
 * widened with its RGB scaled by 2^rgb_scale_log2. */
void dump_texel_rgba(const struct dump_table *t, size_t index, float ret[4]);

/* A file is written under a temporary name beside its final one and renamed
 * over it only when complete: a reader of the dump directory never sees half
 * a file, and a failed write leaves what was there before. */
struct dump_out {
	char tmp[4096];
	int fd;
};

/* Creates "<path>.tmp-<random>" (mode 0644 less the umask), open for
 * writing in o->fd. */
int dump_out_open(struct dump_out *o, const char *path, char *err, size_t err_size);
/* Renames the temporary to path; the caller has closed o->fd (and checked
 * that) and set it to -1. On failure the temporary is removed. */
int dump_out_commit(struct dump_out *o, const char *path, char *err, size_t err_size);
/* Closes o->fd if open and removes the temporary. */
void dump_out_abort(struct dump_out *o);

#endif
