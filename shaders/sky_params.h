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
#define SPEC_EXP_MASK 18	/* bit i: constituent i's profile has an exponential term;
				 * the column pass's also bit 4 + i: in layer 0, 8 + i: in layer 1 */
#define SPEC_MS_SUN_GROUP 19	/* sun angles per multi-scattering invocation */
#define SPEC_SV_AZ_GROUP 20	/* azimuths per sky-view invocation */
#define SPEC_ITER_FIRST 21	/* the first step of the iteration of psi_ms */
#define SPEC_MOMENT_LOBE 22	/* 1 + the constituent whose phase sees the lobe, 0 none */
#define SPEC_DELTA_LOBE 23	/* 1 + the constituent delta-M scales, 0 none */
#define SPEC_PACK_MASK 24	/* the tables pack.comp packs, STATE_BIT()s */
#define SPEC_MS_LANES 25	/* invocations sharing a multi-scattering texel's
				 * directions: 1, or a lane per cell (the grain) */
#define SPEC_LOCAL_X 26		/* the workgroup's size, where a pass takes it */
#define SPEC_LOCAL_Y 27
#define SPEC_LOOKUP_IMAGES 28	/* sky-view and aerial perspective read transmittance
				 * and multi-scattering through sampled images (the
				 * texture units' filtering), not texel buffers */
#define SPEC_CLOUD_LAYERS 29	/* cloud layers drawn (docs/clouds.md): 0 compiles
				 * every cloud term out, so a clear sky is
				 * computed as it was before clouds existed */
#define SPEC_SHADOW_W 30	/* a shadow map's width (shadow_width), 0 without clouds */
#define SPEC_CLOUD_W 31		/* the coverage table's (cloud_width), 0 without clouds */
#define SPEC_MS_UNIFORM 32	/* aerial perspective reads multi-scattering through
				 * the uniform block at BINDING_MULTISCATTER_UBO */
#define SPEC_SV_EYE_UNDER 33	/* sky-view: the observer is under the casters' top
				 * (skyview.comp's march from its first step) */
#define SPEC_TERRAIN 34		/* the shadow maps: a height field casts (terrain=) */
#define SPEC_SV_KEPT 35		/* sky-view: the maps' light at its steps computed,
				 * computed and kept, or read as kept (SV_KEPT_*) */
#define SPEC_CLOUD_PHASES 36	/* the maps' beam: the layers' phases and their
				 * order (CLOUD_PHASES_*; clouds.glsl) */
#define SPEC_COUNT 37

/* SPEC_CLOUD_PHASES's values: every layer of one phase, or ice and water
 * layers with the ice's top higher, or the water's. With two phases
 * the shadow pass also keeps each texel's ice optical depth, after the
 * two maps: texel i's at component i % 4 of vec4 2 W^2 + i / 4. */
#define CLOUD_PHASES_ONE 0
#define CLOUD_PHASES_ICE_OVER 1
#define CLOUD_PHASES_WATER_OVER 2

/* SPEC_SV_KEPT's values: sky-view computes the light the maps let
 * through at each step that reads them, computes it and keeps it at
 * BINDING_SV_LIGHT, or reads it as kept there by a computation of the
 * same maps and rays (eng_clouds.c, eng_sv_kept). */
#define SV_KEPT_OFF 0
#define SV_KEPT_WRITE 1
#define SV_KEPT_READ 2

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
#define BINDING_TRANSMITTANCE_IMG 15	/* transmittance and multi-scattering as */
#define BINDING_MULTISCATTER_IMG 16	/* sampled images (SPEC_LOOKUP_IMAGES) */
#define BINDING_CLOUDS 17		/* struct gpu_clouds: the layers, the field's
					 * place and the shadow maps' frames */
#define BINDING_CLOUD 18		/* the coverage table (cloud.comp writes it) */
#define BINDING_CLOUD_TEX 19		/* the same memory as a lookup */
#define BINDING_SHADOW 20		/* the shadow maps, a slice per light (shadow.comp) */
#define BINDING_SHADOW_TEX 21		/* the same memory as a lookup */
#define BINDING_TERRAIN 22		/* the terrain's 16-bit texels, two a word
					 * (a 1-word dummy without a field) */
#define BINDING_MULTISCATTER_UBO 23	/* the multi-scattering table's float texels
					 * as a uniform block of SKY_MS_UNIFORM_TEXELS
					 * vec4s (SPEC_MS_UNIFORM) */
#define SKY_MS_UNIFORM_TEXELS 1024	/* 16 KiB, the least maxUniformBufferRange */
#define BINDING_SV_LIGHT 24		/* sky-view's kept light per step (SPEC_SV_KEPT) */
#define BINDING_COUNT 25

/* The aerial jobs at BINDING_VIEWS (eng_fill_views, aerial.comp,
 * aerial_resample.comp): a head whose first word is the number of march
 * jobs, then one AerialJob each, the march jobs (a dispatch's z each) and
 * after them the resample jobs. A march job marches a camera's volume or
 * an eye point's panorama (kind); a resample job fills a camera's volume
 * from a panorama. Offsets are in texels of the aerial buffer. */
#define AERIAL_JOB_CAMERA 0u	/* march job kinds */
#define AERIAL_JOB_PANORAMA 1u

/* The multi-scattering directions marched for SPEC_MS_DIRS (msgrid.glsl's
 * MS_MARCHED): half of the 64-direction grid, or both of 2. */
#define SKY_MS_MARCHED(dirs) ((dirs) == 2 ? 2 : 32)

#define SKY_MAX_CONSTITUENTS 4	/* ATMO_MAX_CONSTITUENTS */
#define SKY_GROUND_FIT 8	/* PHASE_GROUND_FIT */

/* One aerial job (std430) as an X-list: V3(name) a vec3 (always followed
 * by a scalar, so that C's float[3] and the shader's vec3 leave no gap),
 * F(name) a float, U(name) a uint. A camera's frame serves camera and
 * resample jobs, a panorama's mapping (struct sky_shm_panorama's fields,
 * as skymap_panorama_uv takes them) panorama and resample jobs.
 * tests/test_params.c checks every member's name, offset and size in the
 * SPIR-V against the C side. */
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
	U(pad0) U(pad1) U(pad2)						         \
	V3(site_east) F(ground_east_km)	/* a march job's eye frame in the        \
					 * observer's (east, north, up from the  \
					 * ground under it): its local east */   \
	V3(site_north) F(ground_north_km) /* north; where its ground point is */ \
	V3(site_up) F(ground_up_km)	/* up (what the shadow maps are read in) */

/* The uniform block (std140, vec4s only, so that C's float[4] matches).
 * X-lists: V(name) a vec4, A(name, n) an array of n vec4, S(name, n) an
 * array of n constituents. Lengths in km, coefficients in 1/km, angles in
 * radians. The lanes that hold a value of their own have names below. */
#define SKY_CONSTITUENT_MEMBERS(V)                                               \
	V(scattering)	/* rgb, w = PHASE_G */                                   \
	V(absorption)	/* rgb, w = PHASE_G1 */                                  \
	V(layer0)	/* LAYER0_WIDTH_KM, then layer 0's exp_term,             \
			 * exp_scale_per_km, linear_per_km */                    \
	V(layer0c_1)	/* LAYER0_CONSTANT, then layer 1's exp_term,             \
			 * exp_scale_per_km, linear_per_km */                    \
	V(layer1c)	/* LAYER1_CONSTANT, PHASE_G2, DELTA_F, DELTA_G */

#define SKY_PARAMS_MEMBERS(V, A, S)                                              \
	V(planet)	/* BOTTOM_RADIUS_KM, TOP_RADIUS_KM, SHELL_KM, OBSERVER_KM */ \
	V(albedo)	/* ground albedo rgb */                                  \
	V(sun_dir)	/* unit xyz, w = SUN_RADIUS_RAD */                       \
	V(sun_illum)	/* lx per channel at the top of the atmosphere */        \
	V(moon_dir)	/* unit xyz, w = MOON_RADIUS_RAD */                      \
	V(moon_illum)                                                            \
	V(cam_fwd)	/* w = CAM_TAN_HALF_VFOV */                              \
	V(cam_right)	/* w = CAM_ASPECT */                                     \
	V(cam_up)	/* w = AERIAL_RANGE_KM */                                \
	V(misc)		/* HORIZON_COS, SKYVIEW_MIN_STEPS, AERIAL_SQUARED,       \
			 * TOP_DISTANCE_KM */                                    \
	S(c, SKY_MAX_CONSTITUENTS)                                               \
	V(night)	/* night-sky floor: rgb zenith cd/m2, w = NIGHT_GAIN */  \
	A(ground_fit, SKY_GROUND_FIT)	/* phase_ground_fit's coefficients,      \
					 * a component per constituent */        \
	V(delta_peak)	/* DELTA_PEAK_H, DELTA_PEAK_SPREAD_RAD */

/* The named lanes, member[lane] alike in C and GLSL: a shader reads
 * P.SUN_RADIUS_RAD, the engine writes p->SUN_RADIUS_RAD. Indexing a
 * vector by a constant is a swizzle, so the passes compile as with .w;
 * splitting the vec4s into float and vec3 members instead made lavapipe
 * compile every pass slower (the private copy, load_params(), grows). */
#define BOTTOM_RADIUS_KM planet[0]
#define TOP_RADIUS_KM planet[1]
#define SHELL_KM planet[2]		/* top - bottom */
#define OBSERVER_KM planet[3]		/* the observer's altitude, >= 0 */
#define SUN_RADIUS_RAD sun_dir[3]	/* the sun's angular radius */
#define MOON_RADIUS_RAD moon_dir[3]
#define CAM_TAN_HALF_VFOV cam_fwd[3]	/* the observer's camera: tan(vfov / 2) */
#define CAM_ASPECT cam_right[3]		/* width / height */
#define AERIAL_RANGE_KM cam_up[3]	/* the aerial volume's depth */
#define HORIZON_COS misc[0]		/* cos of the observer's horizon zenith angle */
#define SKYVIEW_MIN_STEPS misc[1]	/* sky-view's fewest march steps */
#define AERIAL_SQUARED misc[2]		/* a flag: 1 squared slice spacing, 0 linear */
#define TOP_DISTANCE_KM misc[3]		/* H = sqrt(top^2 - bottom^2), the horizontal
					 * distance to the top from the ground */
#define NIGHT_GAIN night[3]		/* c of the floor's L_z (1 + c (1 - mu)) */
#define DELTA_PEAK_H delta_peak[0]	/* delta-M's forward peak: h */
#define DELTA_PEAK_SPREAD_RAD delta_peak[1]	/* and its spread */
/* A constituent's. */
#define PHASE_G scattering[3]		/* the phase's asymmetry g */
#define PHASE_G1 absorption[3]		/* its first Legendre moment */
#define PHASE_G2 layer1c[1]		/* its second */
#define LAYER0_WIDTH_KM layer0[0]	/* where the lower layer ends */
#define LAYER0_CONSTANT layer0c_1[0]	/* the lower layer's constant term */
#define LAYER1_CONSTANT layer1c[0]	/* the upper layer's */
#define DELTA_F layer1c[2]		/* delta-M (its constituent only): the forward
					 * fraction f */
#define DELTA_G layer1c[3]		/* and the truncated phase's g' */

/* The cloud passes' block at BINDING_CLOUDS (std430): the drawn layers
 * (proto/skycloud.h's struct skycloud_layer, float build, 72 bytes each;
 * SPEC_CLOUD_LAYERS of them are read), the field's place, then a shadow
 * map's frame per light, sun then moon (eng_clouds.c, docs/clouds.md,
 * "Shadow maps"), and the field's move since the maps were made (vec4
 * shift: east, north km). A map's texel (i, j) is the light's ray through
 * u U_MIN_KM + (i + 0.5) / U_TEXELS_PER_KM along u, likewise along v,
 * and PLANE_KM along l: depths are counted from there toward -l. */
#define SKY_SHADOW_FRAME_MEMBERS(V)                                              \
	V(u)		/* horizontal axis of the map, w = U_MIN_KM */           \
	V(v)		/* the other axis, up the light's plane, w = V_MIN_KM */ \
	V(l)		/* toward the light, w = PLANE_KM */                     \
	V(scale)	/* U_TEXELS_PER_KM, V_TEXELS_PER_KM, 0, 0 */
#define U_MIN_KM u[3]
#define V_MIN_KM v[3]
#define PLANE_KM l[3]
#define U_TEXELS_PER_KM scale[0]
#define V_TEXELS_PER_KM scale[1]
/* The field's place (the block's vec4 field). */
#define FIELD_OFFSET_EAST_KM field[0]	/* the tables' offset (state_cloud_table_offset_km) */
#define FIELD_OFFSET_NORTH_KM field[1]
#define FIELD_EXTENT_KM field[2]	/* the region's half-width */
#define FIELD_TEXELS_PER_KM field[3]	/* the coverage table's: cloud_width / (2 extent) */
/* The terrain's place (the block's vec4 terrain; 0 without a field). */
#define TERRAIN_HALF_KM terrain[0]	/* half the square's side */
#define TERRAIN_KM_PER_UNIT terrain[1]	/* terrain_height_m / 1000 / 65535 */
#define TERRAIN_TOP_KM terrain[2]	/* the highest texel's height */
#define TERRAIN_WIDTH_TEXELS terrain_size[0]	/* the field's width and height */
#define TERRAIN_HEIGHT_TEXELS terrain_size[1]
/* The most steps of a shadow map's ray across the terrain (shadow.comp). */
#define SKY_SHADOW_TERRAIN_STEPS 256
/* The opaque depth of a texel where no terrain stands (a shadow map's A). */
#define SKY_SHADOW_NO_TERRAIN_KM 1e30

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
	SKY_CONSTITUENT_MEMBERS(SKY_C_VEC4)
};
struct gpu_params {
	SKY_PARAMS_MEMBERS(SKY_C_VEC4, SKY_C_VEC4_ARRAY, SKY_C_CONSTITUENTS)
};
struct gpu_aerial_job {
	SKY_AERIAL_JOB_MEMBERS(SKY_C_VEC3, SKY_C_FLOAT, SKY_C_UINT)
};
struct gpu_shadow_frame {
	SKY_SHADOW_FRAME_MEMBERS(SKY_C_VEC4)
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
	SKY_CONSTITUENT_MEMBERS(SKY_GLSL_VEC4)
};
struct Params {
	SKY_PARAMS_MEMBERS(SKY_GLSL_VEC4, SKY_GLSL_VEC4_ARRAY, SKY_GLSL_CONSTITUENTS)
};
struct AerialJob {
	SKY_AERIAL_JOB_MEMBERS(SKY_GLSL_VEC3, SKY_GLSL_FLOAT, SKY_GLSL_UINT)
};
struct ShadowFrame {
	SKY_SHADOW_FRAME_MEMBERS(SKY_GLSL_VEC4)
};
#undef SKY_GLSL_VEC4
#undef SKY_GLSL_VEC3
#undef SKY_GLSL_FLOAT
#undef SKY_GLSL_UINT
#undef SKY_GLSL_VEC4_ARRAY
#undef SKY_GLSL_CONSTITUENTS
#endif

#endif
