/* sky_params.h - what the engine (C) and the shaders (GLSL) share, defined
 * once: the specialization constants' ids, the descriptor set's bindings and
 * the uniform block's members. The engine includes it through
 * eng_internal.h, the shaders through common.glsl; tests/unit/test_params.c
 * checks the compiled SPIR-V against the C side. */
#ifndef SKY_PARAMS_H
#define SKY_PARAMS_H

/* Specialization constants, by constant_id: what a scene does not need is
 * compiled out. */
#define SPEC_N_CONST 0		/* constituents that are not all zero */
#define SPEC_PHASE_0 1		/* SPEC_PHASE_0 + i: constituent i's phase: 0 none,
				 * 1 Rayleigh, 2 Cornette-Shanks, 3 Henyey-Greenstein */
#define SPEC_PHASE_1 2
#define SPEC_PHASE_2 3
#define SPEC_PHASE_3 4
#define SPEC_STORAGE_F16 5	/* tables are published as float16: each pass records
				 * its largest |RGB| for pack.comp */
#define SPEC_MOON_LIT 6
#define SPEC_GROUND_BLACK 7
#define SPEC_T_W 8		/* the transmittance table's size */
#define SPEC_T_H 9
#define SPEC_M_W 10		/* the multi-scattering table's size */
#define SPEC_M_H 11
#define SPEC_OUT_W 12		/* the size of the table a pass writes */
#define SPEC_OUT_H 13
#define SPEC_OUT_D 14
#define SPEC_STEPS 15		/* its march steps */
#define SPEC_MS_DIRS 16		/* directions of the multi-scattering grid (msgrid.glsl) */
#define SPEC_MULTISCATTER_ON 17	/* the higher orders are on */
#define SPEC_EXP_MASK 18	/* bit i: constituent i's profile has an exponential term */
#define SPEC_MS_SUN_GROUP 19	/* sun angles per multi-scattering invocation */
#define SPEC_SV_AZ_GROUP 20	/* azimuths per sky-view invocation */
#define SPEC_ITER_FIRST 21	/* the first step of the iteration of psi_ms */
#define SPEC_MOMENT_LOBE 22	/* 1 + the constituent whose phase sees the lobe, 0 none */
#define SPEC_DELTA_LOBE 23	/* 1 + the constituent delta-M scales, 0 none */
#define SPEC_PACK_MASK 24	/* the tables pack.comp packs, STATE_BIT()s */
#define SPEC_COUNT 25

/* Bindings of the one descriptor set. The tables are storage buffers in
 * state_table order; transmittance and multi-scattering are read again
 * through texel buffers (the lookups). */
#define BINDING_PARAMS 0		/* the uniform block below */
#define BINDING_TRANSMITTANCE 1
#define BINDING_MULTISCATTER 2
#define BINDING_SKYVIEW 3
#define BINDING_AERIAL 4
#define BINDING_TRANSMITTANCE_TEX 5
#define BINDING_MULTISCATTER_TEX 6
#define BINDING_VIEWS 7			/* the cameras of the aerial volumes */
#define BINDING_COLUMNS 8		/* column densities per transmittance texel */
#define BINDING_ITERATE 9		/* scratch of the iteration of psi_ms */
#define BINDING_MOMENT 10		/* the shape of the multiply scattered light */
#define BINDING_MOMENT_TEX 11		/* the same memory as a lookup */
#define BINDING_COLUMNS_TEX 12		/* the column densities as a lookup */
#define BINDING_PACK 13			/* struct gpu_pack: pack.comp's counts, ranges, scales */
#define BINDING_AERIAL_TEX 14		/* the aerial table's memory as a lookup: the
					 * eye-point panoramas aerial_resample.comp reads */
#define BINDING_COUNT 15

/* The aerial jobs at BINDING_VIEWS (eng_fill_views, aerial.comp,
 * aerial_resample.comp): vec4 0 holds the number of march jobs in x; then
 * AERIAL_JOB_VEC4 vec4s per job, the march jobs (a dispatch's z each) and
 * after them the resample jobs. A march job marches a camera's volume or an
 * eye point's panorama; a resample job fills a camera's volume from a
 * panorama. Offsets are in texels of the aerial buffer, as uint bits. */
#define AERIAL_JOB_VEC4 6
#define AERIAL_JOB_CAMERA 0	/* march job kinds, in vec4 4's w */
#define AERIAL_JOB_PANORAMA 1

#define SKY_MAX_CONSTITUENTS 4	/* ATMO_MAX_CONSTITUENTS */
#define SKY_GROUND_FIT 8	/* PHASE_GROUND_FIT */

/* The uniform block (std140, vec4s only, so that C's float[4] matches).
 * X-lists: V(name) a vec4, A(name, n) an array of n vec4, S(name, n) an
 * array of n constituents. Lengths in km, coefficients in 1/km. */
#define SKY_CONSTITUENT_MEMBERS(V)                                               \
	V(scattering)	/* rgb, w = g */                                         \
	V(absorption)	/* rgb, w = g1, the phase's first Legendre moment */     \
	V(layer0)	/* width_km, exp_term, exp_scale_per_km, linear_per_km */ \
	V(layer0c_1)	/* layer 0's constant, then layer 1's exp_term,          \
			 * exp_scale_per_km, linear_per_km */                    \
	V(layer1c)	/* layer 1's constant, y = g2, the phase's second        \
			 * Legendre moment, z = f, w = g' of the delta-M         \
			 * truncation (the delta-M constituent only) */

#define SKY_PARAMS_MEMBERS(V, A, S)                                              \
	V(planet)	/* bottom radius, top radius, shell, observer altitude */ \
	V(albedo)	/* ground albedo rgb */                                  \
	V(sun_dir)	/* unit, w = angular radius (rad) */                     \
	V(sun_illum)	/* lx per channel at the top of the atmosphere */        \
	V(moon_dir)                                                              \
	V(moon_illum)                                                            \
	V(cam_fwd)	/* w = tan(vfov / 2) */                                  \
	V(cam_right)	/* w = aspect */                                         \
	V(cam_up)	/* w = aerial range km */                                \
	V(misc)		/* x horizon cos of the observer, y sky-view min steps,  \
			 * z aerial squared (1/0), w H = sqrt(top^2 - bottom^2), \
			 * the horizontal distance to the top from the ground */ \
	S(c, SKY_MAX_CONSTITUENTS)                                               \
	V(night)	/* night-sky floor: rgb zenith cd/m2, w horizon gain */  \
	A(ground_fit, SKY_GROUND_FIT)	/* phase_ground_fit's coefficients,      \
					 * a component per constituent */        \
	V(delta_peak)	/* delta-M's forward peak: x = h, y = its spread (rad) */

/* The pack pass (storage=f16, pack.comp), per table in state_table order:
 * the texels to pack (0: not computed this time; the aerial table counts
 * every view's volume), the float bits of the largest |RGB| (the passes'
 * atomicMax) and the published scale, log2, that pack.comp chose. std430.
 * Transmittance never exceeds 1: its pass writes its own binary16 copy,
 * RGB scaled by 2^-SKY_F16_TRANSMITTANCE_LOG2. */
#define SKY_PACK_TABLES 4
#define SKY_F16_TRANSMITTANCE_LOG2 (-15)

#ifdef __STDC__
#include <stdint.h>
struct gpu_pack {
	uint32_t texels[SKY_PACK_TABLES];
	uint32_t max_bits[SKY_PACK_TABLES];
	int32_t scale_log2[SKY_PACK_TABLES];
};

#define SKY_C_VEC4(name) float name[4];
#define SKY_C_VEC4_ARRAY(name, n) float name[n][4];
#define SKY_C_CONSTITUENTS(name, n) struct gpu_constituent name[n];
struct gpu_constituent {
	SKY_CONSTITUENT_MEMBERS(SKY_C_VEC4)
};
struct gpu_params {
	SKY_PARAMS_MEMBERS(SKY_C_VEC4, SKY_C_VEC4_ARRAY, SKY_C_CONSTITUENTS)
};
#undef SKY_C_VEC4
#undef SKY_C_VEC4_ARRAY
#undef SKY_C_CONSTITUENTS
#else
#define SKY_GLSL_VEC4(name) vec4 name;
#define SKY_GLSL_VEC4_ARRAY(name, n) vec4 name[n];
#define SKY_GLSL_CONSTITUENTS(name, n) Constituent name[n];
struct Constituent {
	SKY_CONSTITUENT_MEMBERS(SKY_GLSL_VEC4)
};
struct Params {
	SKY_PARAMS_MEMBERS(SKY_GLSL_VEC4, SKY_GLSL_VEC4_ARRAY, SKY_GLSL_CONSTITUENTS)
};
#undef SKY_GLSL_VEC4
#undef SKY_GLSL_VEC4_ARRAY
#undef SKY_GLSL_CONSTITUENTS
#endif

#endif
