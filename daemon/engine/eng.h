/* eng.h - the LUT engine: Hillaire's four tables on a Vulkan compute device.
 *
 * One engine owns one VkDevice and one queue. Work is submitted without
 * blocking; completion is signalled on an eventfd so that the daemon's loop
 * never waits on the GPU. At most one computation is in flight.
 *
 * Table memory: texels are RGBA, float32 (16 bytes) or float16 (8 bytes)
 * as the state's storage says, rows of width texels, rows bottom-up in v,
 * the aerial volume's slices stacked (see proto/skymap.h for the mappings).
 * The passes compute in float32 whatever the storage; float16 tables are
 * rounded from those values, RGB scaled by a power of two per table so that
 * nothing overflows the half's 65504 nor sinks into its subnormals: the
 * value is RGB 2^eng_table_scale_log2 (A is never scaled).
 *   transmittance  RGB transmittance to the top of the atmosphere, A = 1
 *   multiscatter   RGB psi_ms per unit illuminance (1/sr), A = the share of the
 *                  ground's first bounce in psi_ms (luminance-weighted, [0, 1])
 *   skyview        RGB radiance (cd/m2 per channel when illuminances are in lx),
 *                  A = mean transmittance along the view ray
 *   aerial         RGB in-scattered radiance, A = mean transmittance
 */
#ifndef SKYD_ENG_H
#define SKYD_ENG_H

#include <stddef.h>
#include <stdint.h>

#include "state.h"

struct eng;

struct eng_device {
	uint32_t index;			/* in vkEnumeratePhysicalDevices order */
	int type;			/* VkPhysicalDeviceType */
	uint32_t vendor_id, device_id;
	char name[256];
	char driver[512];
	char type_name[16];		/* "discrete", "integrated", "virtual", "cpu", "other" */
};

struct eng_timing {
	uint32_t computed;		/* STATE_BIT mask of the tables computed */
	double table_ms[STATE_N_TABLES];/* GPU time per table (timestamps), else wall time;
					 * transmittance's includes the column pass,
					 * multi-scattering's the iteration of psi_ms;
					 * with storage=f16 the last one computed
					 * includes the float16 copies (pack.comp) */
	double total_ms;		/* submit to completion, wall clock */
	/* 1 when the column-density pass ran: transmittance is exp(-sum ext_k L_k)
	 * from column densities L_k that depend on the geometry, the profiles
	 * and the table's size and steps only, kept from the last computation
	 * unless one of those changed. */
	int columns;
	double columns_ms;		/* its GPU time (timestamps; the pass writes
					 * the transmittance texels too), else 0 */
	/* The cloud passes' GPU times (timestamps), else 0: the coverage
	 * table's and the shadow maps'; sky-view's table_ms counts them too. */
	double cloud_ms, shadow_ms;
	/* 1 when sky-view read the light the shadow maps let through at its
	 * steps as an earlier computation kept it: the same maps, lights'
	 * frames, field and rays (a light that moved within its map's cell). */
	int skyview_light_kept;
	/* 1 when the cloud tables were made ahead for this computation's
	 * layers, field and lights (eng_submit_ahead), and taken instead of
	 * running the cloud passes. */
	int clouds_ahead;
};

/* Lists the Vulkan devices, at most max of them, into ret (may be NULL when
 * max is 0). Returns the number of devices, or -errno; err says why (no
 * loader: which package to install). */
int eng_list_devices(struct eng_device *ret, size_t max, char *err, size_t err_size);

/* Opens a device. selector: NULL or "" picks by preference (discrete, then
 * integrated, then virtual, then CPU, e.g. lavapipe) unless $SKYD_DEVICE is
 * set; otherwise a device index or a case-insensitive substring of the
 * device's name. On failure returns -errno with a one-line cause in err. */
int eng_new(const char *selector, char *err, size_t err_size, struct eng **ret);
void eng_free(struct eng *e);

const struct eng_device *eng_device(const struct eng *e);

/* The grain the passes are dispatched at. ENG_GRAIN_CPU: each invocation
 * computes several texels of a row, marching their shared rays once (the
 * sun angles of multi-scattering, the azimuths of sky-view), eight by
 * eight invocations a workgroup: few invocations, no shared memory, no
 * barrier, what a CPU device's few threads want. ENG_GRAIN_WIDE: an
 * invocation per texel, and a workgroup per multi-scattering texel whose
 * lanes march its directions and add them in shared memory: the thousands
 * of workgroups a GPU needs. eng_new picks it from the device (CPU devices
 * the CPU grain, any other the wide one) unless $SKYD_GRAIN names one
 * ("cpu" or "wide": a diagnostic and test switch). Both give the same
 * tables within float rounding (tests/numerical/test_grain.c). */
enum eng_grain { ENG_GRAIN_CPU, ENG_GRAIN_WIDE };
enum eng_grain eng_grain(const struct eng *e);
/* "cpu" or "wide". */
const char *eng_grain_name(enum eng_grain g);
/* Forces a grain from the next eng_submit on (tests, diagnostics). */
void eng_set_grain(struct eng *e, enum eng_grain g);
/* Whether sky-view and aerial perspective read the transmittance and
 * multi-scattering tables through sampled images (the texture units'
 * bilinear filtering) or through texel buffers filtered by hand, which the
 * grain chose (buffers at both grains, docs/findings/engine.md) unless
 * $SKYD_LOOKUPS says "images" or "buffers" (a diagnostic and test switch).
 * The texture units may filter with fewer bits than float32: the tables
 * then differ by their rounding (tests/numerical/test_grain.c). */
int eng_lookup_images(const struct eng *e);
/* Sets it from the next eng_submit on. */
void eng_set_lookup_images(struct eng *e, int images);

/* Keeps the compiled pipelines in dir (a VkPipelineCache in a file named
 * after the device), so that a later skyd on the same device and driver
 * builds them from it: reads it now (a file that is missing, unreadable or
 * from another device or driver is left to be rewritten) and writes it
 * whenever a computation made pipelines the file lacks, and at eng_free.
 * dir must exist. Returns 0, or -errno when the cache cannot be created
 * (the engine works on without it). */
int eng_use_cache_dir(struct eng *e, const char *dir, char *err, size_t err_size);
/* The largest table in bytes the device can hold in one storage buffer. */
uint64_t eng_max_table_bytes(const struct eng *e);

/* Starts computing the tables in mask for state s (already validated and
 * resolved), lit by lights (its state_lights_of, which the caller kept:
 * NULL computes them). The
 * caller passes exactly what must be recomputed and nothing else is: the
 * engine keeps the other tables from earlier computations, so the
 * dependencies of mask that are not in it must be valid for s. A size or
 * storage change reallocates; a reallocated dependency of mask is computed
 * too, a reallocated table outside mask's closure is left zeroed. Returns 0, -EBUSY while a computation is in flight,
 * -EINVAL on a bad state, or -EIO on a device error (err says which). */
int eng_submit(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
	       uint32_t mask, char *err, size_t err_size);

/* The cloud tables made ahead (docs/clouds.md, "Maps made ahead"): the
 * engine holds a second set of the coverage table and the shadow maps,
 * which eng_submit_ahead fills for a state the clock is about to reach
 * while the device would idle; a later computation whose layers, field
 * and lights' cells are that state's binds it instead of running the
 * cloud passes, the same bits as if it had run them. Which set holds the
 * cloud tables of s lit by lights (NULL: computed): the bound one (also
 * where s casts nothing), the one made ahead, or neither. */
enum eng_clouds_made { ENG_CLOUDS_NONE, ENG_CLOUDS_BOUND, ENG_CLOUDS_AHEAD };
enum eng_clouds_made eng_clouds_made(const struct eng *e, const struct sky_state *s,
				     const struct state_lights *lights);
/* Starts making the cloud tables of s into the spare set, the bound
 * tables kept: a computation like eng_submit's (eng_complete ends it; its
 * timing's computed holds the cloud tables), which publishes nothing.
 * Returns 0 when started, 1 when there is nothing to make (eng_clouds_made
 * is not NONE, or nothing was computed yet), else as eng_submit. */
int eng_submit_ahead(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		     char *err, size_t err_size);

/* Where a computation's published tables go: into host memory that
 * eng_host_import imported, which the device writes itself (the
 * publisher's slot: no read-back, no copy by the host), or, with base
 * NULL, into the engine's own host copies (eng_table). tables: the tables
 * to write, those computed and those kept from earlier computations (they
 * must be valid for the state), STATE_BIT()s. Offsets are from base, in
 * the published format (float16 with storage=f16); aerial perspective's
 * table_offset is the state's camera's volume, volume_offset[v] volume v
 * of the plan (aplan.h, v >= 1: the views'), panorama_offset[k] its
 * published panorama k; ENG_NOWHERE where there is none. */
#define ENG_NOWHERE UINT64_MAX
#define ENG_MAX_VOLUMES (1 + STATE_MAX_VIEWS)
struct eng_target {
	void *base;
	uint32_t tables;
	uint64_t table_offset[STATE_N_TABLES];
	uint64_t volume_offset[ENG_MAX_VOLUMES];
	uint64_t panorama_offset[ENG_MAX_VOLUMES];
};
/* eng_submit, the tables written where target says (NULL: the tables of
 * mask into the engine's host copies, as eng_submit). With mask 0 the
 * computation only writes the kept tables. */
int eng_submit_to(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		  uint32_t mask, const struct eng_target *target, char *err, size_t err_size);

/* Imports bytes of host memory at base (the publisher's mapping) for
 * eng_target: the device then writes the tables there itself
 * (VK_EXT_external_memory_host). base and bytes must be multiples of the
 * device's minImportedHostPointerAlignment, and the memory must stay
 * mapped until eng_host_release. Returns 0, or -EOPNOTSUPP (no extension,
 * or the alignment does not hold: err says which) or -errno; at most two
 * regions at a time (-ENOSPC). */
int eng_host_import(struct eng *e, void *base, size_t bytes, char *err, size_t err_size);
/* Whether the engine's host copies (eng_table) hold every table of tables
 * as last computed. */
int eng_host_fresh(const struct eng *e, uint32_t tables);
/* Forgets the import of base, waiting first for a computation in flight
 * that writes there; no-op for memory not imported. */
void eng_host_release(struct eng *e, void *base);
/* Where float16 storage breaks, in the tables of mask as last computed:
 * RGB values that are not finite (infinite or NaN: the scale keeps every
 * finite float32 value finite, so only a computation that produced them
 * leaves them), and sky radiance (sky-view and aerial perspective) at or
 * above the night sky's zenith luminance (state_night_floor; any radiance
 * without one) that was stored as a half subnormal, with fewer than 11
 * significant bits: a sky spanning more than 2^29 between its brightest
 * value and the night floor. Values below the floor (the ground just under
 * the observer, seen through metres of air) may lose their precision.
 * All 0 for float32 storage. */
struct eng_f16_range {
	uint64_t overflow;		/* values, every table */
	uint64_t subnormal;		/* radiance values of sky-view and aerial */
	uint64_t radiance_values;	/* RGB values of sky-view and aerial examined */
};
/* Whether r says float16 storage broke: any value not finite, or more than
 * 1 % of the radiance values subnormal. */
int eng_f16_broken(const struct eng_f16_range *r);
void eng_f16_range(const struct eng *e, const struct sky_state *s, uint32_t mask,
		   struct eng_f16_range *ret);

/* Compute pipelines created since eng_new: one per specialization variant
 * of a pass, cached (up to 32 per pass), so a repeat adds none. */
uint64_t eng_pipelines_created(const struct eng *e);
/* The pipelines the submitted computation waits for: a variant not seen
 * before is compiled on the waiter thread (seconds on lavapipe), not in
 * eng_submit, and the computation is submitted by eng_complete once they
 * are made. 0 from then on. */
int eng_pipelines_ordered(const struct eng *e);
/* Blocks until the pipelines ordered are made; the completion stays for
 * eng_complete, which then submits the computation. */
void eng_wait_orders(const struct eng *e);

/* An eventfd that becomes readable when the submitted work has finished. */
int eng_event_fd(const struct eng *e);
/* Non-blocking: 0 and the timing once finished, -EAGAIN before. */
int eng_complete(struct eng *e, struct eng_timing *ret, char *err, size_t err_size);
/* Drops the kept column densities, so that the next computation of the
 * transmittance table does all of its work (benchmarks of a computation
 * from scratch). */
void eng_forget_columns(struct eng *e);
/* Whether cameras on one eye point (the state's camera and views of the
 * same altitude and position) share one march of aerial perspective, a
 * panorama of the eye point resampled into each volume (the default), or
 * each volume is marched on its own: the reference the shared volumes are
 * measured against (tests/numerical/test_views.c, docs/performance.md). Applies
 * from the next eng_submit. */
void eng_set_view_sharing(struct eng *e, int share);
/* Blocks until the submitted work has finished. */
int eng_wait(struct eng *e, struct eng_timing *ret, char *err, size_t err_size);
/* eng_submit (lights computed from s) then eng_wait. */
int eng_compute(struct eng *e, const struct sky_state *s, uint32_t mask,
		struct eng_timing *ret, char *err, size_t err_size);

/* The table as computed by the last completed computation, in host memory,
 * in the state's storage format. Valid until the next eng_submit or
 * eng_free. ret_bytes may be NULL. NULL when the engine holds no host copy
 * of it: on a device whose memory the host cannot read cheaply, a table
 * written only into imported memory (eng_target) has none, unless the
 * storage is float16 (eng_f16_range reads it). */
const void *eng_table(const struct eng *e, enum state_table t, size_t *ret_bytes);
/* The published aerial panoramas of the last completed computation (those
 * views of form panorama read), one after the other in aplan_make's order
 * (the plan of its state, with the engine's sharing), each
 * aplan_panorama_texels float32 RGBA texels: RGB the logarithm of the
 * radiance, A the transmittance (struct sky_shm_panorama). NULL when the
 * plan publishes none. Valid as eng_table's. */
const void *eng_panoramas(const struct eng *e, size_t *ret_bytes);
/* The cloud tables as the last computation that made them left them
 * (docs/clouds.md, "In the tables"): t STATE_CLOUD_COVERAGE, the coverage
 * table (cloud_width^2 float32 RGBA, a layer a channel), or
 * STATE_CLOUD_SHADOW, the shadow maps (two of shadow_width^2 float32 RGBA,
 * the sun's then the moon's). NULL while none holds the state's field (a
 * clear sky). Valid until the next eng_submit or eng_free. */
const void *eng_cloud_table(const struct eng *e, int t, size_t *ret_bytes);
/* A shadow map's frame as the sky marches read it (sky_params.h's
 * SKY_SHADOW_FRAME_MEMBERS: u, v, l and scale, 4 floats each; the
 * field's shift since the maps were made included), for the
 * sun (0) and the moon (1, zero while it lights nothing) of s lit by
 * lights; returns the layers drawn (0: all zero). */
int eng_cloud_frames(const struct sky_state *s, const struct state_lights *lights,
		     float ret[2][16]);
/* Whether anything casts into the shadow maps of s: a drawn layer or the
 * terrain (the maps exist, SPEC_SHADOW_W is their width, and a region
 * publishes them). */
bool eng_shadow_casters(const struct sky_state *s);

/* k such that the table's RGB values are its stored RGB times 2^k: 0 for
 * float32 storage; for float16, the pack pass's choice, the smallest k
 * with the table's largest |RGB| times 2^-k at most 65504 (transmittance,
 * whose largest value is 1, gets -15). Changes with every computation of
 * the table, as eng_table does. */
int32_t eng_table_scale_log2(const struct eng *e, enum state_table t);

#endif
