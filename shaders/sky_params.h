/* sky_params.h - what the engine (C) and the shaders (GLSL) share, defined
 * once: the specialization constants' ids, the descriptor set's bindings and
 * the uniform block's members. The engine includes it through
 * eng_internal.h, the shaders through common.glsl; tests/test_params.c
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
 * aerial_resample.comp): a head whose first word is the number of march
 * jobs, then one AerialJob each, the march jobs (a dispatch's z each) and
 * after them the resample jobs. A march job marches a camera's volume or
 * an eye point's panorama (kind); a resample job fills a camera's volume
 * from a panorama. Offsets are in texels of the aerial buffer. */
#define AERIAL_JOB_CAMERA 0u	/* march job kinds */
#define AERIAL_JOB_PANORAMA 1u

#define SKY_MAX_CONSTITUENTS 4	/* ATMO_MAX_CONSTITUENTS */
#define SKY_GROUND_FIT 8	/* PHASE_GROUND_FIT */

/* The shared structs as X-lists: V(name) a vec4, V3(name) a vec3 (always
 * followed by a scalar, so that C's float[3] and the shader's vec3 leave
 * no gap), F(name) a float, U(name) a uint, A(name, n) an array of n vec4,
 * S(name, n) an array of n constituents. Lengths in km, coefficients in
 * 1/km, angles in radians. tests/test_params.c checks every member's name,
 * offset and size in the SPIR-V against the C side. */

/* One aerial job (std430). A camera's frame serves camera and resample
 * jobs, a panorama's mapping (struct sky_shm_panorama's fields, as
 * skymap_panorama_uv takes them) panorama and resample jobs. */
#define SKY_AERIAL_JOB_MEMBERS(V3, F, U)                                         \
	V3(fwd) F(tan_half_vfov)	/* a camera's forward; tan(vfov / 2) */  \
	V3(right) F(aspect)		/* its right; width / height */          \
	V3(up) F(eye_km)		/* its up; the eye's altitude (any job) */ \
	F(azimuth0_rad)			/* a panorama's column 0 azimuth */      \
	F(azimuth_step_rad)		/* between columns */                    \
	F(row0) F(row_step)		/* row j at x = row0 + j row_step, x =   \
					 * sign(e) sqrt(|e|), e above horizon */ \
	F(horizon_rad)			/* the eye's horizon elevation */        \
	F(width) F(height)		/* columns (stored), rows */             \
	F(full_circle)			/* 1: the last column repeats column 0 */ \
	V3(sun) U(out_texel)		/* the sun in the eye's local frame; the \
					 * output's first texel */               \
	V3(moon) U(kind)		/* the moon likewise; AERIAL_JOB_* of a  \
					 * march job */                          \
	U(panorama_texel)		/* a resample job's panorama */          \
	U(pad0) U(pad1) U(pad2)

/* The uniform block (std140). */
#define SKY_CONSTITUENT_MEMBERS(V, V3, F)                                        \
	V3(scattering) F(g)	/* per channel; the phase's asymmetry g */       \
	V3(absorption) F(g1)	/* per channel; the phase's first Legendre moment */ \
	V(layer0)		/* the lower layer's profile: exp_term,          \
				 * exp_scale_per_km, linear_per_km, constant */  \
	V(layer1)		/* the upper layer's, the same terms */          \
	F(layer0_width_km)	/* where the lower layer ends */                 \
	F(g2)			/* the phase's second Legendre moment */         \
	F(delta_f)		/* delta-M (the delta-M constituent only): the   \
				 * forward fraction f */                          \
	F(delta_g)		/* and the truncated phase's g' */

#define SKY_PARAMS_MEMBERS(V, V3, F, U, A, S)                                    \
	F(bottom_radius_km) F(top_radius_km)                                     \
	F(shell_km)		/* top - bottom */                               \
	F(observer_km)		/* the observer's altitude, >= 0 */              \
	V(albedo)		/* ground albedo rgb */                          \
	V3(sun_dir) F(sun_radius_rad)	/* unit; angular radius */               \
	V(sun_illum)		/* lx per channel at the top of the atmosphere */ \
	V3(moon_dir) F(moon_radius_rad)                                          \
	V(moon_illum)                                                            \
	V3(cam_fwd) F(cam_tan_half_vfov)                                         \
	V3(cam_right) F(cam_aspect)                                              \
	V3(cam_up) F(aerial_range_km)                                            \
	F(horizon_cos)		/* of the observer */                            \
	F(skyview_min_steps)                                                     \
	U(aerial_squared)	/* 1: squared slice spacing, 0: linear */        \
	F(top_distance_km)	/* H = sqrt(top^2 - bottom^2), the horizontal    \
				 * distance to the top from the ground */        \
	S(c, SKY_MAX_CONSTITUENTS)                                               \
	V3(night) F(night_gain)	/* night-sky floor: rgb zenith cd/m2; the horizon \
				 * gain c of L_z (1 + c (1 - mu)) */              \
	A(ground_fit, SKY_GROUND_FIT)	/* phase_ground_fit's coefficients,      \
					 * a component per constituent */        \
	F(delta_peak_h)		/* delta-M's forward peak: its h */              \
	F(delta_peak_spread_rad)	/* and its spread */                     \
	F(pad0) F(pad1)

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
#define SKY_C_VEC3(name) float name[3];
#define SKY_C_FLOAT(name) float name;
#define SKY_C_UINT(name) uint32_t name;
#define SKY_C_VEC4_ARRAY(name, n) float name[n][4];
#define SKY_C_CONSTITUENTS(name, n) struct gpu_constituent name[n];
struct gpu_constituent {
	SKY_CONSTITUENT_MEMBERS(SKY_C_VEC4, SKY_C_VEC3, SKY_C_FLOAT)
};
struct gpu_params {
	SKY_PARAMS_MEMBERS(SKY_C_VEC4, SKY_C_VEC3, SKY_C_FLOAT, SKY_C_UINT, SKY_C_VEC4_ARRAY,
			   SKY_C_CONSTITUENTS)
};
struct gpu_aerial_job {
	SKY_AERIAL_JOB_MEMBERS(SKY_C_VEC3, SKY_C_FLOAT, SKY_C_UINT)
};
/* The buffer at BINDING_VIEWS: this head, then the jobs. */
struct gpu_aerial_head {
	uint32_t n_march;
	uint32_t pad[3];
};
#undef SKY_C_VEC4
#undef SKY_C_VEC3
#undef SKY_C_FLOAT
#undef SKY_C_UINT
#undef SKY_C_VEC4_ARRAY
#undef SKY_C_CONSTITUENTS
#else
#define SKY_GLSL_VEC4(name) vec4 name;
#define SKY_GLSL_VEC3(name) vec3 name;
#define SKY_GLSL_FLOAT(name) float name;
#define SKY_GLSL_UINT(name) uint name;
#define SKY_GLSL_VEC4_ARRAY(name, n) vec4 name[n];
#define SKY_GLSL_CONSTITUENTS(name, n) Constituent name[n];
struct Constituent {
	SKY_CONSTITUENT_MEMBERS(SKY_GLSL_VEC4, SKY_GLSL_VEC3, SKY_GLSL_FLOAT)
};
struct Params {
	SKY_PARAMS_MEMBERS(SKY_GLSL_VEC4, SKY_GLSL_VEC3, SKY_GLSL_FLOAT, SKY_GLSL_UINT,
			   SKY_GLSL_VEC4_ARRAY, SKY_GLSL_CONSTITUENTS)
};
struct AerialJob {
	SKY_AERIAL_JOB_MEMBERS(SKY_GLSL_VEC3, SKY_GLSL_FLOAT, SKY_GLSL_UINT)
};
#undef SKY_GLSL_VEC4
#undef SKY_GLSL_VEC3
#undef SKY_GLSL_FLOAT
#undef SKY_GLSL_UINT
#undef SKY_GLSL_VEC4_ARRAY
#undef SKY_GLSL_CONSTITUENTS
#endif

#endif
