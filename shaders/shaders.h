/* shaders.h - the embedded SPIR-V, one entry per shader: a table's pass
 * each in state_table order, then the passes that produce no table
 * (SHADER_COLUMNS, SHADER_MSITERATE, SHADER_PACK) and the views'
 * resampling of aerial perspective (SHADER_AERIAL_RESAMPLE), and the cloud
 * passes' coverage table and shadow maps (SHADER_CLOUD, SHADER_SHADOW). The engine's
 * passes name theirs (daemon/engine/eng_pass.c). */
#ifndef SKYD_SHADERS_H
#define SKYD_SHADERS_H

#include <stddef.h>
#include <stdint.h>

enum { SHADER_TRANSMITTANCE, SHADER_MULTISCATTER, SHADER_SKYVIEW, SHADER_AERIAL, SHADER_COLUMNS,
       SHADER_MSITERATE, SHADER_PACK, SHADER_AERIAL_RESAMPLE, SHADER_CLOUD, SHADER_SHADOW,
       SHADER_COUNT };

struct shader_code {
	const char *name;
	const uint32_t *words;
	size_t bytes;
};

extern const struct shader_code shader_code[SHADER_COUNT];

#endif
