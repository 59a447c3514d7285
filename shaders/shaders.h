/* shaders.h - the embedded SPIR-V, one entry per table in state_table order,
 * then the passes that produce no table (SHADER_COLUMNS, SHADER_MSITERATE,
 * SHADER_PACK) and the views' resampling of aerial perspective
 * (SHADER_AERIAL_RESAMPLE). */
#ifndef SKYD_SHADERS_H
#define SKYD_SHADERS_H

#include <stddef.h>
#include <stdint.h>

enum { SHADER_COLUMNS = 4, SHADER_MSITERATE = 5, SHADER_PACK = 6, SHADER_AERIAL_RESAMPLE = 7,
       SHADER_COUNT = 8 };

struct shader_code {
	const char *name;
	const uint32_t *words;
	size_t bytes;
};

extern const struct shader_code shader_code[SHADER_COUNT];

#endif
