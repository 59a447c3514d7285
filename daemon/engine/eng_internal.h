/* eng_internal.h - what the files of the engine (eng_*.c) share: struct eng,
 * the device's buffers, the specialization key and the internal helpers. */
#ifndef SKYD_ENG_INTERNAL_H
#define SKYD_ENG_INTERNAL_H

#include <errno.h>
#include <pthread.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <time.h>

#include "aplan.h"
#include "eng.h"
#include "phase.h"
#include "vkcheck.h"
#include "vkfn.h"

#include "shaders.h"
#include "sky_params.h"
#include "skycloud.h"

#define MAX_PIPELINES 32	/* cached variants per shader */
#define N_SPEC SPEC_COUNT
/* The aerial jobs (sky_params.h): the head, then at most a march job per
 * volume and per panorama and a resample job per volume (the state's
 * camera and STATE_MAX_VIEWS views). */
#define VIEW_BUFFER_BYTES                                                                 \
	(sizeof(struct gpu_aerial_head) + 3 * APLAN_CAMERAS * sizeof(struct gpu_aerial_job))

/* The tables later passes look up: transmittance and multi-scattering. */
#define N_LOOKUPS 2
#define ENG_LOOKUP_TABLES (STATE_BIT(STATE_TRANSMITTANCE) | STATE_BIT(STATE_MULTISCATTER))
/* The bindings (sky_params.h): the tables in state_table order, then the
 * lookups, then the engine's internal buffers. */
#define N_BINDINGS BINDING_COUNT
_Static_assert(BINDING_TRANSMITTANCE + STATE_TRANSMITTANCE == 1 &&
	       BINDING_TRANSMITTANCE + STATE_AERIAL == BINDING_AERIAL &&
	       BINDING_TRANSMITTANCE_TEX == 1 + STATE_N_TABLES &&
	       BINDING_TRANSMITTANCE_TEX + STATE_MULTISCATTER == BINDING_MULTISCATTER_TEX &&
	       BINDING_VIEWS == BINDING_TRANSMITTANCE_TEX + N_LOOKUPS,
	       "sky_params.h's bindings follow enum state_table");
_Static_assert(SKY_MAX_CONSTITUENTS == ATMO_MAX_CONSTITUENTS && SKY_GROUND_FIT == PHASE_GROUND_FIT,
	       "sky_params.h's array lengths");
/* The compute passes in the order a computation records them; each is a
 * row of eng_pass.c's table (what it reads and writes, when it runs, its
 * workgroups), which says how to add one. */
enum pass {
	PASS_COLUMNS,		/* column densities of the transmittance texels,
				 * and the texels */
	PASS_TRANSMITTANCE,	/* the texels from kept column densities */
	PASS_MULTISCATTER,
	PASS_MSITERATE,		/* the iteration of psi_ms, thick atmospheres */
	PASS_LOOKUP_IMAGES,	/* transmittance and multi-scattering into images */
	PASS_CLOUD,		/* the cloud coverage table */
	PASS_SHADOW,		/* the lights' shadow maps of the layers */
	PASS_SKYVIEW,
	PASS_AERIAL,		/* every march job: volumes and panoramas */
	PASS_RESAMPLE,		/* the views' volumes from the panoramas */
	PASS_PACK,		/* the binary16 copies of storage=f16 */
	N_PASSES
};
_Static_assert(SKY_PACK_TABLES == STATE_N_TABLES, "pack.comp packs every table");

/* The grain the passes are dispatched at (eng_grain.c): how many texels
 * one invocation computes and how many invocations share one texel. */
struct grain {
	enum eng_grain kind;
	/* Texels of a row one invocation shares its rays between: sun angles
	 * of multi-scattering, azimuths of sky-view (more share more work
	 * until the registers run out; docs/findings/engine.md). */
	uint32_t ms_sun_group, sv_az_group;
	/* A lane per marched cell of one multi-scattering texel (a workgroup
	 * a texel), or 1: each invocation marches every cell in turn. */
	bool ms_wide;
	/* Sky-view and aerial perspective read transmittance and
	 * multi-scattering through sampled images, filtered by the texture
	 * units, instead of texel buffers filtered by hand. */
	bool lookup_images;
	/* Aerial perspective reads multi-scattering through a uniform block
	 * (BINDING_MULTISCATTER_UBO) where the table fits one. */
	bool ms_uniform;
};

/* phase_ground_excess of one constituent, kept while its phase stays: it
 * costs about 30000 phase evaluations, more than a sun change's tables. */
struct ground_cache {
	bool valid;
	enum atmo_phase kind;
	double g;
	double fit[PHASE_GROUND_FIT];	/* phase_ground_fit of phase_ground_excess */
	double legendre[2];	/* phase_legendre, l = 1 and 2: a quadrature too */
};

/* The block at BINDING_CLOUDS (clouds.glsl's CloudBlock, std430). */
struct gpu_clouds {
	struct skycloud_layer layer[SKYCLOUD_MAX_LAYERS];
	float field[4];				/* FIELD_* lanes */
	float terrain[4];			/* TERRAIN_* lanes */
	uint32_t terrain_size[4];		/* TERRAIN_*_TEXELS; [2..3] the
						 * field's hash: a new field is a
						 * new block */
	struct gpu_shadow_frame frame[2];	/* sun, moon */
	/* The field's move since the tables' offset (FIELD_OFFSET_*), east
	 * and north km, and 0, 0: the maps' readers shift by it
	 * (state_cloud_table_offset_km). Not part of what the tables are
	 * made from. */
	float shift_km[4];
};

/* Specialization constants, by constant_id (SPEC_* in sky_params.h). */
struct spec {
	int32_t v[N_SPEC];
};

struct pipeline {
	struct spec key;
	VkPipeline pipe;
};

/* A variant a plan lacks, made on the waiter thread (eng_make_orders). */
struct pipeline_order {
	int shader;
	struct spec key;
};


struct gpu_buffer {
	VkBuffer buf;
	VkDeviceMemory mem;
	void *map;		/* host-visible buffers only */
	VkDeviceSize bytes;
};

/* The cloud tables of one block: the coverage table and the shadow maps
 * (sun then moon, then the ice depths) with their lookups; valid: they
 * hold what key gives (its lanes before shift_km). moon_zero: the moon's
 * map is all zeros, as an unlit moon leaves it (record_shadow). */
struct cloud_set {
	struct gpu_buffer cloud, shadow;
	VkBufferView cloud_view, shadow_view;
	bool valid, moon_zero;
	struct gpu_clouds key;
};

/* What the column densities depend on: the shell's geometry, the density
 * profiles of the constituents in the shaders, the table's size and steps
 * (the column pass's specialization). Coefficients are not in it. */
struct column_key {
	float planet[3];	/* bottom, top, shell: the observer left out */
	float h_top;		/* TOP_DISTANCE_KM */
	float layers[ATMO_MAX_CONSTITUENTS][12];
	struct spec spec;
};

/* One pass of one computation (eng_pass.c): whether it runs, its
 * specialization and pipeline, its workgroups. */
struct pass_run {
	bool on;
	struct spec key;
	VkPipeline pipe;
	uint32_t groups[3];
};

/* What sky-view's kept light (BINDING_SV_LIGHT) is of: its pass's
 * constants (SPEC_SV_KEPT aside), the planet and the observer, its fewest
 * steps, and the cloud block whole: the maps' layers, field and lights'
 * frames, and the field's shift since the maps. */
struct sv_light_key {
	struct spec spec;
	float planet[4];
	float min_steps;
	struct gpu_clouds clouds;
};

/* What one computation runs: a pass_run per pass, the key of the column
 * densities it leaves, the iteration's later steps' pipeline and count,
 * the aerial jobs (eng_fill_views) and the last table of mask, which the
 * pack pass's time counts in. */
struct plan {
	uint32_t mask;
	struct pass_run run[N_PASSES];
	struct column_key key;
	VkPipeline iterate_later;
	uint32_t iterations;
	uint32_t aerial_march, aerial_resample;
	int last_table;
	int n_clouds;			/* layers drawn: SPEC_CLOUD_LAYERS */
	bool eye_under;			/* SPEC_SV_EYE_UNDER */
	struct gpu_clouds clouds;	/* the block, as eng_fill_clouds made it */
	struct sv_light_key sv_key;	/* sky-view's, its SPEC_SV_KEPT chosen by it */
	bool sv_keyed;			/* sv_key holds sky-view's key (it reads maps) */
};

struct eng {
	struct vkfn vk;
	void *loader;
	VkInstance instance;
	VkPhysicalDevice phys;
	struct eng_device info;
	VkPhysicalDeviceMemoryProperties mem_props;
	VkPhysicalDeviceLimits limits;
	uint32_t queue_family;
	float timestamp_period_ns;
	bool timestamps;
	VkDevice dev;
	VkQueue queue;
	VkDescriptorSetLayout set_layout;
	VkPipelineLayout pipe_layout;
	VkDescriptorPool desc_pool;
	VkDescriptorSet set;
	VkShaderModule modules[SHADER_COUNT];
	struct pipeline pipes[SHADER_COUNT][MAX_PIPELINES];
	int n_pipes[SHADER_COUNT];
	uint64_t pipelines_created;
	/* A new variant takes lavapipe seconds to compile: a plan that lacks
	 * one orders it, the waiter thread makes the orders (compiling: the
	 * job in flight), and eng_complete then submits the deferred call. */
	struct pipeline_order orders[N_PASSES + 1];
	int n_orders;
	bool compiling;
	struct {
		struct sky_state s;
		struct state_lights lights;
		uint32_t mask;
		struct eng_target target;
		bool has_target;
		int orders;
	} deferred;
	/* eng_use_cache_dir: the pipelines' cache and its file, written when
	 * pipelines_created passed pipelines_saved. */
	VkPipelineCache pipeline_cache;
	char *cache_path;
	uint64_t pipelines_saved;
	struct grain grain;
	uint32_t subgroup_size;		/* the device's, for the grain's choice */
	VkCommandPool cmd_pool;
	VkCommandBuffer cmd;
	VkQueryPool queries;
	VkFence fence;

	struct gpu_buffer params;
	struct gpu_buffer views;			/* the aerial jobs (eng_fill_views) */
	/* Cameras on one eye point share one march, a panorama resampled
	 * into each volume (aerial_resample.comp); off: each volume is
	 * marched (eng_set_view_sharing, the reference). */
	bool share_views;
	struct aplan aplan;				/* of the last computation submitted */
	/* Where the aerial buffer's panoramas start on the device, after the
	 * volumes and their binary16 copy; in the readback buffer the
	 * published ones follow the published volumes. */
	size_t panorama_offset;
	VkBufferView aerial_view;			/* BINDING_AERIAL_TEX */
	/* Device memory: every table in float32 RGBA, as the passes compute
	 * it whatever the storage; with storage=f16 its binary16 copy follows
	 * (pack.comp), and that copy is what reaches host memory. */
	struct gpu_buffer table[STATE_N_TABLES];
	struct gpu_buffer readback[STATE_N_TABLES];	/* host memory, the published format */
	/* Whether the host copy (readback, or the table itself where direct)
	 * holds the table as last computed: not where a computation wrote it
	 * only into imported memory. */
	bool host_fresh[STATE_N_TABLES];
	/* Where the device's memory is the host's, cached (lavapipe, most
	 * integrated GPUs), the tables are read where the passes wrote them,
	 * from published_offset on: no copy, no readback buffer. */
	bool direct[STATE_N_TABLES];
	size_t published_offset[STATE_N_TABLES];
	size_t table_bytes[STATE_N_TABLES];		/* the published table (readback) */
	size_t device_bytes[STATE_N_TABLES];		/* float32 part plus the copy */
	/* The published RGB scale, log2, of each table as last computed
	 * (eng_table_scale_log2): pack.comp's choice for storage=f16, else 0. */
	int32_t rgb_scale_log2[STATE_N_TABLES];
	/* Transmittance and multi-scattering are read by the later passes
	 * through texel buffers (float32 RGBA): the sampler's gathers are
	 * vectorized, where a storage-buffer load with a varying index is a
	 * loop over the lanes on lavapipe. */
	VkBufferView lookup_view[N_LOOKUPS];
	/* The multi-scattering texels BINDING_MULTISCATTER_UBO covers: the
	 * table's float texels, at most SKY_MS_UNIFORM_TEXELS of them. */
	VkDeviceSize ms_uniform_bytes;
	/* The same tables as sampled images (grain.lookup_images), copied
	 * from the buffers after each computation of them; made whatever the
	 * grain, since every pipeline's descriptors name them. images_valid:
	 * they hold the tables as last computed; images_new: their layout is
	 * still undefined. */
	struct lookup_image {
		VkImage img;
		VkDeviceMemory mem;
		VkImageView view;
		uint32_t width, height;
	} lookup_image[N_LOOKUPS];
	VkSampler sampler;
	bool images_valid, images_new;
	/* struct gpu_pack, host-visible: the engine writes the texel counts
	 * before a storage=f16 computation and reads the scales after it. */
	struct gpu_buffer pack;
	bool pack_in_flight;
	/* Column densities per transmittance texel (vec4, one per constituent):
	 * recomputed only when column_key changes, so that a change of the
	 * coefficients alone runs the tiny transmittance pass only. */
	struct gpu_buffer columns;
	/* The shape of the multiply scattered light, an RGBA float32 texel
	 * per multi-scattering texel (ms_source in common.glsl). */
	struct gpu_buffer moment;
	VkBufferView moment_view;
	VkBufferView columns_view;	/* COLUMNS_TEX_BINDING */
	struct ground_cache ground[ATMO_MAX_CONSTITUENTS];	/* by gpu constituent */
	struct ground_cache delta;	/* fill_delta's: the truncated phase's fit, f and g' in legendre */
	struct column_key column_key;
	bool columns_valid;
	/* The iteration of psi_ms (shaders/msiterate.comp): its output as the
	 * table holds it (float32 RGBA), copied over the table after each
	 * step, then L2 as float32 RGBA per texel. */
	struct gpu_buffer ms_iterate;

	/* The cloud passes (eng_clouds.c): the block, and the cloud tables
	 * the passes read and publish (ct, bound), one texel each while no
	 * layer is drawn. ct_ahead: a second set, made for a state the clock
	 * is about to reach (eng_submit_ahead) or left by the last swap;
	 * ahead_flight: the computation in flight makes it (the sets
	 * swapped until it completes); took_ahead: the one in flight took it
	 * (eng_timing.clouds_ahead); clouds_rebind: the descriptors name the
	 * other set. */
	struct gpu_buffer clouds;
	struct cloud_set ct, ct_ahead;
	bool ahead_flight, took_ahead, clouds_rebind;
	bool resubmitting;		/* eng_complete submits a deferred call */
	uint64_t shadow_map_bytes;	/* the two maps, before the ice depths */
	/* BINDING_TERRAIN: the field's texels as uploaded, terrain_hash
	 * names them (0: the dummy). */
	struct gpu_buffer terrain;
	uint64_t terrain_hash;
	/* Sky-view's light per step (SPEC_SV_KEPT), 16 bytes where it is not
	 * kept; sv_light_valid: it holds what sv_light_key gives. sv_last:
	 * the key of the last sky-view computed with casters, if
	 * sv_last_valid. */
	struct gpu_buffer sv_light;
	bool sv_light_valid, sv_last_valid;
	struct sv_light_key sv_light_key, sv_last;

	/* Host memory the device writes published tables into
	 * (eng_host_import, eng_host.c), and where the computation in flight
	 * writes them (eng_target; has_target false: none). */
	bool host_import;			/* VK_EXT_external_memory_host enabled */
	VkDeviceSize import_alignment;
	PFN_vkGetMemoryHostPointerPropertiesEXT get_host_pointer_props;
	struct host_region {
		void *base;
		size_t bytes;
		VkDeviceMemory mem;
		VkBuffer buf;
	} regions[2];
	struct eng_target target;
	bool has_target;
	struct plan flight;			/* of the computation in flight */

	/* Completion: a waiter thread waits on the fence, then writes the eventfd. */
	int event_fd;
	pthread_t waiter;
	bool waiter_started;
	pthread_mutex_t lock;
	pthread_cond_t cond;
	bool pending, finished, quit;
	VkResult wait_result;
	uint32_t in_flight_mask;
	struct timespec submit_time;
};

void eng_set_err(char *err, size_t n, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/* eng_grain.c: the grain eng_new starts with, from the device's
 * properties and $SKYD_GRAIN. */
void eng_grain_choose(struct eng *e);

/* eng_tables.c: the tables' buffers. */
/* Texels of table t in s, every aerial volume of the engine's plan counted. */
uint64_t eng_table_texels(const struct eng *e, const struct sky_state *s, int t);
/* Bytes of table t's float32 texels on the device. */
VkDeviceSize eng_float_bytes(const struct eng *e, const struct sky_state *s, int t);
/* Whether the device can hold every table of s: 0, or -EINVAL with the
 * table and the limit in err. */
int eng_check_limits(const struct eng *e, const struct sky_state *s, char *err, size_t err_size);
/* (Re)allocates the buffers whose size or storage changed; ret_lost gets
 * the tables whose contents were lost. */
int eng_ensure_tables(struct eng *e, const struct sky_state *s, uint32_t *ret_lost, char *err,
		      size_t err_size);
void eng_free_tables(struct eng *e);

/* Records the move of the lookup images from an undefined layout to the
 * one the descriptors say, where they were just made. */
void eng_record_image_layouts(struct eng *e);

/* eng_pass.c: the passes. */
/* Fills params and pl for s and mask, ordering the pipelines it lacks
 * (e->orders: pl is not to be recorded while there are any); -EINVAL
 * where a dispatch exceeds the device's limits. */
int eng_make_plan(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		  uint32_t mask, struct gpu_params *params, struct plan *pl, char *err,
		  size_t err_size);
/* Records pl's passes into e->cmd (begun), with the barriers their reads
 * and writes need; every shader write is pending after it. */
void eng_record_passes(struct eng *e, const struct sky_state *s, const struct plan *pl);
/* The GPU time of each pass of pl from the timestamps, into t. */
int eng_pass_times(struct eng *e, const struct plan *pl, struct eng_timing *t, char *err,
		   size_t err_size);
/* Makes the ordered pipelines and clears the orders; on the waiter
 * thread, while nothing else touches the pipelines. */
VkResult eng_make_orders(struct eng *e);
/* Destroys the cached pipelines. */
void eng_free_pipelines(struct eng *e);

/* eng_clouds.c: the cloud passes' inputs and buffers. */
/* The block for s lit by lights; returns the layers drawn (0: a clear
 * sky, ret zeroed). */
int eng_fill_clouds(const struct sky_state *s, const struct state_lights *lights,
		    struct gpu_clouds *ret);
/* mask with the cloud tables a computation of it needs for c (n layers):
 * none for a clear sky; both where sky-view or aerial perspective would
 * read maps made for another block. */
uint32_t eng_cloud_mask(struct eng *e, const struct sky_state *s, const struct gpu_clouds *c, int n,
			uint32_t mask);
/* (Re)allocates the cloud buffers for s (one texel each without a drawn
 * layer); *rebind when one changed. */
int eng_ensure_clouds(struct eng *e, const struct sky_state *s, bool *rebind, char *err,
		      size_t err_size);
void eng_free_clouds(struct eng *e);
/* Before a computation of s: where the set made ahead holds s's block
 * and the bound one does not, swaps them: true. */
bool eng_take_ahead(struct eng *e, const struct sky_state *s, const struct state_lights *lights);
/* After a computation made ahead, failed or not: the bound set back. */
void eng_end_ahead(struct eng *e);
/* SPEC_SV_KEPT for the sky-view pass of pl with constants key: off where
 * no map is read or the light is too large to keep, read where the kept
 * light is of this computation's maps and rays, write otherwise. */
int eng_sv_kept(const struct eng *e, const struct sky_state *s, struct plan *pl,
		const struct spec *key);

/* eng_host.c: imported host memory. */
/* Records the copies of the published tables (after the passes) into
 * target's memory, or with target NULL, into the host copies of the tables
 * of copy; marks the host copies fresh or stale. */
void eng_record_publish(struct eng *e, const struct sky_state *s, const struct eng_target *target,
			uint32_t copy);
void eng_host_free(struct eng *e);

/* eng_cache.c: writes the pipelines' cache file (eng_use_cache_dir), if
 * there is one and pipelines were made since; a failure leaves the old
 * file. */
void eng_save_cache(struct eng *e);

/* eng_device.c: device memory. buffer_new maps host-visible memory; the
 * vec4 buffers are float32 RGBA storage with a texel view on them. */
int eng_buffer_new(struct eng *e, VkDeviceSize bytes, VkBufferUsageFlags usage,
		   VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer,
		   struct gpu_buffer *ret, char *err, size_t err_size);
void eng_buffer_free(struct eng *e, struct gpu_buffer *b);
int eng_vec4_buffer_new(struct eng *e, VkDeviceSize bytes, struct gpu_buffer *ret,
			VkBufferView *ret_view, char *err, size_t err_size);
void eng_vec4_buffer_free(struct eng *e, struct gpu_buffer *b, VkBufferView *view);
/* The descriptor type of a binding of the one descriptor set. */
VkDescriptorType eng_binding_type(int binding);

/* eng_params.c: the uniform block and the specialization of the passes. */
/* Fills the uniform block and the constants every pass starts from for s
 * lit by lights; keeps the phases' fits in e while a constituent's phase
 * stays. */
void eng_fill_params(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		     struct gpu_params *p, struct spec *base);
/* The aerial jobs of s (sky_params.h, VIEW_BUFFER_BYTES) as planned by
 * p: the volumes marched on their own, then the panoramas (at texel
 * pano_base of the aerial buffer, one after the other), each with the
 * volumes resampled from it. ret_march and ret_resample get the jobs'
 * counts (the dispatches' z). */
void eng_fill_views(const struct sky_state *s, const struct aplan *p, uint64_t pano_base,
		    void *out, uint32_t *ret_march, uint32_t *ret_resample);
struct spec eng_pass_spec(const struct spec *base, const struct sky_state *s, int t,
			  const struct grain *g);
struct spec eng_column_spec(const struct spec *base, const struct sky_state *s);
void eng_column_key(const struct gpu_params *p, const struct spec *column_spec,
		    struct column_key *ret);

#endif
