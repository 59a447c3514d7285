/* eng_grain.c - the grain the passes are dispatched at, chosen per device
 * at start-up (eng.h, enum eng_grain) and handed to the shaders as
 * specialization constants (eng_params.c, eng_pass.c). */
#include "eng_internal.h"

#include <stdlib.h>
#include <string.h>

/* A CPU device's few threads want few, fat invocations: one marches a
 * ray once for several texels (4 sun angles of multi-scattering, 12
 * azimuths of sky-view: docs/findings/engine.md has the sweep), and a
 * barrier would turn every invocation into a coroutine (lavapipe). */
static const struct grain cpu_grain = {
	.kind = ENG_GRAIN_CPU, .ms_sun_group = 4, .sv_az_group = 12, .ms_wide = false,
	.ms_uniform = true,
};

/* A GPU wants thousands of workgroups: a multi-scattering texel per
 * workgroup, a lane per direction, added in shared memory; a sky-view
 * texel per invocation. Multi-scattering marches each direction once per
 * texel instead of once per four: four times the arithmetic, spread over
 * 256 times the workgroups. */
static const struct grain wide_grain = {
	.kind = ENG_GRAIN_WIDE, .ms_sun_group = 1, .sv_az_group = 1, .ms_wide = true,
};

const char *eng_grain_name(enum eng_grain g)
{
	return g == ENG_GRAIN_WIDE ? "wide" : "cpu";
}

enum eng_grain eng_grain(const struct eng *e)
{
	return e->grain.kind;
}

void eng_set_grain(struct eng *e, enum eng_grain g)
{
	bool images = e->grain.lookup_images;
	e->grain = g == ENG_GRAIN_WIDE ? wide_grain : cpu_grain;
	e->grain.lookup_images = images;
}

int eng_lookup_images(const struct eng *e)
{
	return e->grain.lookup_images;
}

void eng_set_lookup_images(struct eng *e, int images)
{
	e->grain.lookup_images = images != 0;
}

/* Every conformant device can run the wide grain (a workgroup of 32
 * invocations and 3.4 KB of shared memory are below Vulkan's minimum
 * limits, 128 and 16 KB), so the device's type decides: a CPU keeps the
 * CPU grain. The limits are checked all the same, since the choice must
 * never make a device fail. */
void eng_grain_choose(struct eng *e)
{
	const char *force = getenv("SKYD_GRAIN");
	bool fits = e->limits.maxComputeWorkGroupInvocations >= 32 &&
		    e->limits.maxComputeWorkGroupSize[0] >= 32 &&
		    e->limits.maxComputeSharedMemorySize >= 4096;
	enum eng_grain g = e->info.type == VK_PHYSICAL_DEVICE_TYPE_CPU || !fits ? ENG_GRAIN_CPU
										: ENG_GRAIN_WIDE;

	const char *lookups = getenv("SKYD_LOOKUPS");

	if (force && !strcmp(force, "wide") && fits)
		g = ENG_GRAIN_WIDE;
	else if (force && !strcmp(force, "cpu"))
		g = ENG_GRAIN_CPU;
	e->grain = g == ENG_GRAIN_WIDE ? wide_grain : cpu_grain;
	if (lookups && !strcmp(lookups, "images"))
		e->grain.lookup_images = true;
	else if (lookups && !strcmp(lookups, "buffers"))
		e->grain.lookup_images = false;
}
