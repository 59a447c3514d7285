/* sky_set.h - one request through libsky and the generation its reply
 * names: what the tests of libsky's readers wait for next. */
#ifndef SKYD_SKY_SET_H
#define SKYD_SKY_SET_H

#include <stdint.h>
#include <stdlib.h>

#include "sky.h"
#include "test.h"

/* Sends line on c; the generation its reply names, 0 (and a failed CHECK)
 * when it was refused or named none. */
static inline uint32_t set_and_generation(sky_client *c, const char *line)
{
	sky_reply *rep = NULL;
	uint32_t g = 0;
	CHECK(sky_request(c, line, &rep) == 0);
	const char *v = rep ? sky_reply_get(rep, "generation") : NULL;
	CHECK(v != NULL);
	if (v)
		g = (uint32_t)strtoul(v, NULL, 10);
	sky_reply_free(rep);
	return g;
}

#endif
