/* vk_or_skip.h - open the engine or exit 77 (skipped) where this machine
 * has no Vulkan loader or device. */
#ifndef SKYD_VK_OR_SKIP_H
#define SKYD_VK_OR_SKIP_H

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>

#include "eng.h"

static inline struct eng *vk_or_skip(void)
{
	char err[512];
	struct eng *e;
	int rc = eng_new(NULL, err, sizeof(err), &e);
	if (rc == -ENOENT || rc == -ENODEV) {
		printf("skipped: %s\n", err);
		exit(77);
	}
	if (rc < 0) {
		fprintf(stderr, "eng_new: %s\n", err);
		exit(1);
	}
	return e;
}

#endif
