/* frame_kit.h - what the tests of the render clients share: a frame read
 * back from its PNG, a client program run to its end with its output
 * kept, the generation it says it drew, and a client drawing without end
 * whose frames are read as they come. */
#ifndef SKYD_FRAME_KIT_H
#define SKYD_FRAME_KIT_H

#include <fcntl.h>
#include <limits.h>
#include <png.h>
#include <poll.h>
#include <signal.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <sys/wait.h>
#include <unistd.h>

struct image {
	uint32_t w, h;
	uint8_t *rgb;
};

/* The PNG at path as 8-bit RGB; rgb NULL when it cannot be read. */
static inline int image_read(const char *path, struct image *ret)
{
	png_image im = { .version = PNG_IMAGE_VERSION };
	if (!png_image_begin_read_from_file(&im, path)) {
		fprintf(stderr, "%s: %s\n", path, im.message);
		ret->rgb = NULL;
		return -1;
	}
	im.format = PNG_FORMAT_RGB;
	ret->w = im.width;
	ret->h = im.height;
	ret->rgb = malloc(PNG_IMAGE_SIZE(im));
	if (!ret->rgb || !png_image_finish_read(&im, NULL, ret->rgb, 0, NULL)) {
		free(ret->rgb);
		ret->rgb = NULL;
		return -1;
	}
	return 0;
}

static inline int px(const struct image *im, uint32_t x, uint32_t y, int c)
{
	return im->rgb[((size_t)y * im->w + x) * 3 + c];
}

/* Starts argv with its stdout (and stderr too when with_stderr) into a
 * pipe whose reading end goes to *ret_fd: its pid, or -1. */
static inline pid_t spawn_piped(const char *const *argv, bool with_stderr, int *ret_fd)
{
	int p[2];
	if (pipe2(p, O_CLOEXEC) < 0)
		return -1;
	pid_t pid = fork();
	if (pid == 0) {
		dup2(p[1], 1);
		if (with_stderr)
			dup2(p[1], 2);
		execv(argv[0], (char *const *)argv);
		_exit(127);
	}
	close(p[1]);
	if (pid < 0) {
		close(p[0]);
		return -1;
	}
	*ret_fd = p[0];
	return pid;
}

/* Runs argv to its end with stdout (and stderr too when with_stderr) into
 * out; the exit status or -1. */
static inline int run(const char *const *argv, bool with_stderr, char *out, size_t size)
{
	int fd;
	pid_t pid = spawn_piped(argv, with_stderr, &fd);
	if (pid < 0)
		return -1;
	size_t n = 0;
	ssize_t k;
	while ((k = read(fd, out + n, size - 1 - n)) > 0 && n + 1 < size)
		n += (size_t)k;
	out[n] = 0;
	close(fd);
	int status;
	if (waitpid(pid, &status, 0) < 0 || !WIFEXITED(status))
		return -1;
	return WEXITSTATUS(status);
}

/* The generation after "generation " in a program's output, or -1. */
static inline long generation_of(const char *out)
{
	const char *g = strstr(out, "generation ");
	return g ? strtol(g + 11, NULL, 10) : -1;
}

/* A client drawing without end (--forever), its output read line by
 * line: each "frame N generation G PATH" line, the others kept in log
 * (and echoed, for the test's own output). */
struct frame_stream {
	pid_t pid;
	int fd;
	char buf[8192];
	size_t len;
	char path[PATH_MAX];	/* of the last frame */
	char log[4096];
	size_t log_len;
};

/* Starts argv with its stdout (and stderr too when with_stderr) read by
 * st. 0 or -1. */
static inline int frame_stream_start(struct frame_stream *st, const char *const *argv, bool with_stderr)
{
	*st = (struct frame_stream){ .fd = -1 };
	st->pid = spawn_piped(argv, with_stderr, &st->fd);
	return st->pid < 0 ? -1 : 0;
}

/* Keeps one line that is not a frame's in st->log. */
static inline void frame_stream_log(struct frame_stream *st, const char *line)
{
	printf("%s\n", line);
	size_t room = sizeof(st->log) - st->log_len;
	int n = snprintf(st->log + st->log_len, room, "%s\n", line);
	st->log_len += n < 0 ? 0 : (size_t)n < room ? (size_t)n : room - 1;
}

/* The generation of the next frame line (its path into st->path), or -1
 * when none came within timeout_ms or the client ended. */
static inline long frame_stream_next(struct frame_stream *st, int timeout_ms)
{
	for (;;) {
		char *nl = memchr(st->buf, '\n', st->len);
		if (nl) {
			*nl = 0;
			long g = -2, n;
			unsigned long long gen;
			char path[PATH_MAX];
			int got = sscanf(st->buf, "frame %ld generation %llu %4095s", &n, &gen, path);
			if (got >= 2)
				g = (long)gen;
			else
				frame_stream_log(st, st->buf);
			if (got == 3)
				memcpy(st->path, path, strlen(path) + 1);
			size_t k = (size_t)(nl - st->buf) + 1;
			memmove(st->buf, nl + 1, st->len - k);
			st->len -= k;
			if (g >= 0)
				return g;
			continue;
		}
		struct pollfd p = { st->fd, POLLIN, 0 };
		if (st->len == sizeof(st->buf) || poll(&p, 1, timeout_ms) <= 0)
			return -1;
		ssize_t k = read(st->fd, st->buf + st->len, sizeof(st->buf) - st->len);
		if (k <= 0)
			return -1;
		st->len += (size_t)k;
	}
}

/* Reads frames until one drew generation >= gen: that generation, or the
 * last drawn when none did within timeout_ms (frames keep coming, so the
 * deadline is the whole wait's). */
static inline long frame_stream_until(struct frame_stream *st, long gen, int timeout_ms)
{
	struct timespec t0, t;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	long g;
	for (;;) {
		g = frame_stream_next(st, timeout_ms);
		clock_gettime(CLOCK_MONOTONIC, &t);
		long ms = (long)(t.tv_sec - t0.tv_sec) * 1000 + (t.tv_nsec - t0.tv_nsec) / 1000000;
		if (g < 0 || g >= gen || ms >= timeout_ms)
			return g;
	}
}

/* Ends the client with SIGTERM: its exit status, or -1 when it did not
 * exit by itself (a crash, a signal it did not handle). */
static inline int frame_stream_stop(struct frame_stream *st)
{
	int status = 0;
	kill(st->pid, SIGTERM);
	int r = waitpid(st->pid, &status, 0);
	close(st->fd);
	return r < 0 || !WIFEXITED(status) ? -1 : WEXITSTATUS(status);
}

#endif
