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

#include "sky_params.h"

#define MAX_PIPELINES 32	/* cached variants per pass */
#define N_SPEC SPEC_COUNT
/* Texels of a row one invocation shares its rays between: sun angles of
 * multi-scattering, azimuths of sky-view (more azimuths share more work
 * until the registers run out; docs/findings/engine.md). */
#define MS_SUN_GROUP 4
#define SV_AZ_GROUP 12
/* The aerial jobs (sky_params.h): the head, then at most a march job per
 * volume and per panorama and a resample job per volume (the state's
 * camera and STATE_MAX_VIEWS views). */
#define VIEW_BUFFER_BYTES                                                                 \
	(sizeof(struct gpu_aerial_head) + 3 * APLAN_CAMERAS * sizeof(struct gpu_aerial_job))

/* The tables later passes look up: transmittance and multi-scattering. */
#define N_LOOKUPS 2
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
/* Compute passes: one per table, then the column densities (SHADER_COLUMNS),
 * the iteration of psi_ms (SHADER_MSITERATE), the binary16 copies of
 * storage=f16 (SHADER_PACK, timed with the last table's pass) and the
 * views' resampling of the aerial panoramas (SHADER_AERIAL_RESAMPLE, timed
 * with the aerial pass). */
#define PASS_COLUMNS STATE_N_TABLES
#define PASS_MSITERATE (STATE_N_TABLES + 1)
#define PASS_PACK (STATE_N_TABLES + 2)
#define PASS_RESAMPLE (STATE_N_TABLES + 3)
#define N_PASSES (STATE_N_TABLES + 4)
_Static_assert(SKY_PACK_TABLES == STATE_N_TABLES, "pack.comp packs every table");

/* phase_ground_excess of one constituent, kept while its phase stays: it
 * costs about 30000 phase evaluations, more than a sun change's tables. */
struct ground_cache {
	bool valid;
	enum atmo_phase kind;
	double g;
	double fit[PHASE_GROUND_FIT];	/* phase_ground_fit of phase_ground_excess */
	double legendre[2];	/* phase_legendre, l = 1 and 2: a quadrature too */
};

/* Specialization constants, by constant_id (SPEC_* in sky_params.h). */
struct spec {
	int32_t v[N_SPEC];
};

struct pipeline {
	struct spec key;
	VkPipeline pipe;
};

struct gpu_buffer {
	VkBuffer buf;
	VkDeviceMemory mem;
	void *map;		/* host-visible buffers only */
	VkDeviceSize bytes;
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
	VkShaderModule modules[N_PASSES];
	struct pipeline pipes[N_PASSES][MAX_PIPELINES];
	int n_pipes[N_PASSES];
	uint64_t pipelines_created;
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
	bool columns_in_flight;
	/* The iteration of psi_ms (shaders/msiterate.comp): its output as the
	 * table holds it (float32 RGBA), copied over the table after each
	 * step, then L2 as float32 RGBA per texel. */
	struct gpu_buffer ms_iterate;
	uint32_t iterations_in_flight;

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
struct spec eng_pass_spec(const struct spec *base, const struct sky_state *s, int t);
struct spec eng_column_spec(const struct spec *base, const struct sky_state *s);
void eng_column_key(const struct gpu_params *p, const struct spec *column_spec,
		    struct column_key *ret);

#endif
