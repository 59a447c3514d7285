/* shaders.c - the SPIR-V of the compute passes, compiled at build time. */
#include "shaders.h"

#include "transmittance.spv.h"
#include "multiscatter.spv.h"
#include "skyview.spv.h"
#include "aerial.spv.h"
#include "columns.spv.h"
#include "msiterate.spv.h"
#include "pack.spv.h"
#include "aerial_resample.spv.h"
#include "cloud.spv.h"
#include "shadow.spv.h"

const struct shader_code shader_code[SHADER_COUNT] = {
	{ "transmittance", shader_transmittance_spv, sizeof(shader_transmittance_spv) },
	{ "multiscatter", shader_multiscatter_spv, sizeof(shader_multiscatter_spv) },
	{ "skyview", shader_skyview_spv, sizeof(shader_skyview_spv) },
	{ "aerial", shader_aerial_spv, sizeof(shader_aerial_spv) },
	{ "columns", shader_columns_spv, sizeof(shader_columns_spv) },
	{ "msiterate", shader_msiterate_spv, sizeof(shader_msiterate_spv) },
	{ "pack", shader_pack_spv, sizeof(shader_pack_spv) },
	{ "aerial_resample", shader_aerial_resample_spv, sizeof(shader_aerial_resample_spv) },
	{ "cloud", shader_cloud_spv, sizeof(shader_cloud_spv) },
	{ "shadow", shader_shadow_spv, sizeof(shader_shadow_spv) },
};
