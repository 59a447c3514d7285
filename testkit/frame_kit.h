/* frame_kit.h - what the tests of the render clients share: a frame read
 * back from its PNG, a client program run to its end with its output
 * kept, and the generation it says it drew. */
#ifndef SKYD_FRAME_KIT_H
#define SKYD_FRAME_KIT_H

#include <fcntl.h>
#include <png.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
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

/* Runs argv to its end with stdout (and stderr too when with_stderr) into
 * out; the exit status or -1. */
static inline int run(const char *const *argv, bool with_stderr, char *out, size_t size)
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
	size_t n = 0;
	ssize_t k;
	while ((k = read(p[0], out + n, size - 1 - n)) > 0 && n + 1 < size)
		n += (size_t)k;
	out[n] = 0;
	close(p[0]);
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

#endif
