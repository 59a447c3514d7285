/* skyproto.h - the contract between skyd and its clients: protocol version,
 * limits, error codes, and the layout of the shared memory.
 *
 * This is the only header the daemon and the clients both include (with
 * skymap.h for the uv mappings). Any change bumps SKY_PROTO_VERSION or
 * SKY_SHM_LAYOUT_VERSION. PROTOCOL.md beside it is the script writer's manual.
 */
#ifndef SKYD_SKYPROTO_H
#define SKYD_SKYPROTO_H

#include <stdint.h>

/* Text protocol: greeting "OK skyd <SKY_PROTO_VERSION>". */
#define SKY_PROTO_VERSION "7.1"
#define SKY_PROTO_LINE_MAX 4096		/* bytes per request line, newline included */

/* ACK codes: "ACK [code] {verb} message". */
enum sky_ack {
	SKY_ACK_SYNTAX = 1,		/* malformed line, key=value expected */
	SKY_ACK_ARG = 2,		/* a value that is not valid for its key */
	SKY_ACK_PERMISSION = 4,		/* the peer's role may not do this */
	SKY_ACK_UNKNOWN = 5,		/* unknown verb */
	SKY_ACK_NO_EXIST = 50,		/* unknown key, table or view */
	SKY_ACK_RANGE = 51,		/* a number outside its range */
	SKY_ACK_LIMIT = 52,		/* a per-client bound was reached */
	SKY_ACK_TOO_LONG = 53,		/* request line over SKY_PROTO_LINE_MAX */
	SKY_ACK_STATE = 54,		/* not allowed in this state (end without batch) */
	SKY_ACK_ENGINE = 60,		/* the device failed; last good tables stay */
};

/* Shared memory ------------------------------------------------------------
 *
 * One memfd: a header, then n_slots slots of slot_bytes each, the first at
 * header_bytes. Every offset is from the start of the mapping and aligned to
 * 64 bytes. All multi-byte fields are native-endian (same machine).
 *
 * Reading a slot (never blocks the writer, holds nothing):
 *   s1 = atomic_load_acquire(&slot->seq); if odd, retry or take another slot
 *   copy or sample what is needed
 *   atomic_thread_fence(acquire); s2 = atomic_load_relaxed(&slot->seq)
 *   if s1 != s2 the copy is torn: retry
 * The newest slot is header->current_slot; header->generation increments on
 * every publication and is the futex word to wait on. The last slot
 * (n_slots - 1) is spare: skyd writes a generation computed ahead of its
 * apply time there (apply_time_ns > 0, generation above the current
 * slot's) before it makes it current at that instant; a reader that honours
 * apply times takes it once apply_time_ns <= CLOCK_REALTIME now and bounds
 * its futex wait by that instant (PROTOCOL.md, "Switching at an apply
 * time"). When the layout
 * changes (new sizes), the old region gets superseded = 1 and one last
 * generation increment to wake its waiters; the new memfd arrives on the
 * control socket with a "layout:" line (PROTOCOL.md).
 */
#define SKY_SHM_MAGIC 0x31594b53u	/* "SKY1" little-endian */
#define SKY_SHM_LAYOUT_VERSION 8u
#define SKY_SHM_MAX_TABLES 6u
#define SKY_SHM_MIN_SLOTS 3u
/* Views (`view add`): at most this many, each with its aerial perspective
 * (a volume or its eye point's panorama: enum sky_view_form). */
#define SKY_SHM_MAX_VIEWS 8u
#define SKY_SHM_VIEW_NAME_MAX 32u

enum sky_shm_table_id {
	SKY_TABLE_TRANSMITTANCE = 0,
	SKY_TABLE_MULTISCATTER = 1,
	SKY_TABLE_SKYVIEW = 2,
	SKY_TABLE_AERIAL = 3,
	/* The cloud tables (layout 7), in the directory only while a cloud
	 * layer is drawn (n_tables 6), always RGBA32F, never scaled
	 * (docs/clouds.md, "Published"). */
	SKY_TABLE_CLOUD = 4,		/* coverage: cloud_width^2, RGBA = layers 1-4's coverage */
	SKY_TABLE_SHADOW = 5,		/* shadow maps: shadow_width^2 x depth 2 (sun, moon) */
};

/* RGB of an RGBA16F table is stored scaled: the value is the stored RGB
 * times 2^state.rgb_scale_log2[id] of the slot (a power of two, so exact),
 * chosen per table and per slot from the table's largest value so that no
 * sky overflows binary16's 65504 nor sinks into its subnormals. A is never
 * scaled. RGBA32F tables have scale 0 (stored as they are). */
enum sky_shm_format {
	SKY_FORMAT_RGBA32F = 1,		/* 16 bytes a texel */
	SKY_FORMAT_RGBA16F = 2,		/* 8 bytes a texel, IEEE binary16 */
};

struct sky_shm_table {
	uint32_t id;			/* enum sky_shm_table_id */
	uint32_t format;		/* enum sky_shm_format */
	uint32_t width, height, depth;	/* depth 1 for 2-D tables */
	uint32_t texel_bytes;
	uint64_t offset;		/* from the start of a slot */
	uint64_t bytes;
};

/* The state that produced a slot, and how its tables are stored. Angles in
 * radians, lengths in km, directions as unit vectors in the observer's
 * east-north-up frame. */
struct sky_shm_state {
	double utc_unix_s;		/* simulation time, NaN when angles were set directly */
	double latitude_rad, longitude_rad;	/* the clock's site; NaN as utc_unix_s */
	double altitude_km;		/* observer above the ground */
	double bottom_radius_km, top_radius_km;
	double ground_albedo[3];
	double sun_direction[3];
	double sun_illuminance_lx[3];	/* per channel, top of the atmosphere */
	double sun_angular_radius_rad;
	double moon_direction[3];
	double moon_illuminance_lx[3];	/* 0 when the moon lights nothing */
	double moon_angular_radius_rad;
	double camera_forward[3], camera_right[3], camera_up[3];
	double camera_vfov_rad, camera_aspect;
	double aerial_range_km;
	uint32_t aerial_squared;	/* 1: squared slice spacing, 0: linear */
	uint32_t reserved0;
	/* By enum sky_shm_table_id: RGB = stored RGB * 2^rgb_scale_log2 (see
	 * enum sky_shm_format); 0 for float32 tables. The views' aerial
	 * volumes share the aerial table's. */
	int32_t rgb_scale_log2[SKY_SHM_MAX_TABLES];
	/* The light sensor's suggested EV100 (sensor_mode=exposure, as of the
	 * slot's publication); NaN when none. */
	double exposure_ev100;
	double reserved[12];
};

/* One drawn cloud layer (layout 7): the first 18 fields are
 * proto/skycloud.h's struct skycloud_layer (float build) field for field,
 * 72 bytes that a client copies into a GLSL SkycloudLayer array (std430)
 * as they are; then the layer's phase and albedo. */
struct sky_shm_cloud_layer {
	int32_t type;			/* enum skycloud_type */
	uint32_t seed, index;		/* cloud_seed; the layer's own noise, 0..3 */
	float cover;			/* [0, 1] */
	float base_km, top_km;		/* above the ground under the observer */
	float inv_thickness_per_km;
	float threshold, inv_edge;	/* the coverage fBm's threshold, 1 / soft edge */
	float inv_bottom_fade, inv_top_fade, anvil;
	float extinction_per_km;	/* at density 1, 550 nm, grey */
	float erosion, inv_keep;
	float coverage_scale;		/* cells per km of the coverage's coarsest octave */
	float detail_scale;		/* and of the detail noise's */
	float profile_integral;
	float phase_g;			/* Henyey-Greenstein asymmetry */
	float albedo;			/* single-scattering albedo */
};

/* The cloud field of a slot (layout 7; docs/clouds.md): the layers as
 * skyd draws them, where the wind has put the field, and the frames of
 * the shadow maps (SKY_TABLE_SHADOW). n_layers 0: no layer, every other
 * field 0 but the transmittances (1) and, where the terrain casts, the
 * shadow maps' frames and shadow_lights. */
struct sky_shm_clouds {
	uint32_t n_layers;		/* layers[0 .. n_layers) */
	uint32_t shadow_lights;		/* bit 0: the sun's map is valid, bit 1: the moon's
					 * (its slice zeros where not) */
	double extent_km;		/* half-width of the square region around the observer */
	double offset_km[2];		/* the wind's offset (east, north), subtracted from
					 * field coordinates before the noise */
	/* The wind's move since the tables were made (east, north km): the
	 * coverage table holds the field at offset_km - table_shift_km, so
	 * field coordinates (x, y) read it at (x, y) - table_shift_km. The
	 * shadow rows below include it already. skyd keeps the tables while
	 * the wind carries the field within a few shadow texels. */
	double table_shift_km[2];
	double period_km;		/* the field repeats every period_km (SKYCLOUD_PERIOD_KM) */
	double placed_utc_s;		/* the simulated second it was placed for; NaN: still */
	/* The cloud's transmittance from the observer toward the sun and the
	 * moon (a march of skycloud_optical_depth): multiply the slot's
	 * illuminance by it for the light that reaches the observer. */
	double sun_transmittance, moon_transmittance;
	struct sky_shm_cloud_layer layers[4];
	/* Per light (sun, moon), where a point p (east, north, up km from the
	 * ground under the observer) falls in its shadow map, as
	 * proto/skycloudmarch.h's struct skycloud_shadow_frame takes it: the
	 * map's texture coordinates u = row_u . (p, 1), v = row_v . (p, 1)
	 * (outside [0, 1]: no cloud), and the depth from the map's plane,
	 * growing away from the light, row_depth . (p, 1). A texel's RGBA:
	 * front depth km R, mean extinction per km G, maximum optical depth
	 * B, the terrain's opaque depth km A (1e30: none); (0, 0, 0, A) where
	 * the ray meets no cloud. The optical depth at depth d is
	 * min(B, G max(0, d - R)), and beyond A the light is gone. */
	double shadow_row_u[2][4], shadow_row_v[2][4], shadow_row_depth[2][4];
};

/* How a view's aerial perspective is published (`view add form=`). */
enum sky_view_form {
	/* A volume of the aerial table's format and size, in the view's
	 * camera, at header view_offset + index * view_stride in the slot. */
	SKY_VIEW_VOLUME = 0,
	/* The panorama of the view's eye point (struct sky_shm_panorama),
	 * which every view of that form on the same eye point shares: skyd
	 * marches an eye point once, whatever the number of its views. */
	SKY_VIEW_PANORAMA = 1,
};

/* The panorama of an eye point: aerial perspective toward a grid of
 * directions in the eye's local east-north-up frame, and along each at
 * the aerial table's slices (skymap_aerial_depth_km, the slot state's
 * aerial_range_km and aerial_squared). Always RGBA32F, never scaled: RGB
 * is the natural logarithm of the radiance (the aerial table's units),
 * A the mean transmittance, so that filtering interpolates the radiance
 * geometrically (below the horizon it goes as 1 / sin of the
 * depression). Texel (i, j, k) at offset + ((k * height + j) * width + i)
 * * 16. Columns and rows: skymap_panorama_uv() with the fields below. */
struct sky_shm_panorama {
	uint64_t offset;		/* of texel 0, from the start of the slot */
	uint64_t bytes;			/* width * height * depth * 16 */
	uint32_t width, height, depth;	/* columns, rows, slices */
	uint32_t full_circle;		/* 1: column width - 1 repeats column 0 */
	double azimuth0_rad;		/* column 0's azimuth, east of north */
	double azimuth_step_rad;	/* between columns */
	double row0, row_step;		/* row j at x = row0 + j * row_step, x =
					 * sign(e) sqrt(|e|), e the elevation above
					 * horizon_rad in radians */
	double horizon_rad;		/* the eye's geometric horizon (<= 0) */
};

/* One view: a camera and its aerial perspective. Directions as in
 * sky_shm_state, in the view's local frame (PROTOCOL.md, views). */
struct sky_shm_view {
	char name[SKY_SHM_VIEW_NAME_MAX];	/* NUL-terminated */
	double altitude_km;		/* the view's eye above the ground */
	double camera_forward[3], camera_right[3], camera_up[3];
	double camera_vfov_rad, camera_aspect;
	uint32_t form;			/* enum sky_view_form */
	uint32_t reserved0;
	struct sky_shm_panorama panorama;	/* form SKY_VIEW_PANORAMA; else 0 */
};

struct sky_shm_slot {
	uint32_t seq;			/* odd while written, even when stable (atomic) */
	uint32_t valid_tables;		/* bit (1 << sky_shm_table_id) per valid table */
	uint64_t generation;		/* the generation this slot was published in */
	int64_t apply_time_ns;		/* CLOCK_REALTIME at which it becomes current; 0 now;
					 * never hand out a slot whose instant is ahead */
	uint64_t checksum;		/* of the state and the valid tables, sky_shm_checksum_words */
	struct sky_shm_state state;
	uint32_t n_views;		/* views[0 .. n_views) describe this slot's views */
	uint32_t valid_views;		/* bit i: view i's volume or panorama is valid */
	struct sky_shm_view views[SKY_SHM_MAX_VIEWS];
	struct sky_shm_clouds clouds;	/* layout 7; table_shift_km: 8 */
};

struct sky_shm_header {
	uint32_t magic;			/* SKY_SHM_MAGIC */
	uint32_t layout_version;	/* SKY_SHM_LAYOUT_VERSION */
	uint32_t uv_mapping_version;	/* SKYMAP_VERSION */
	uint32_t header_bytes;		/* offset of slot 0 */
	uint32_t n_slots;		/* >= SKY_SHM_MIN_SLOTS */
	uint32_t n_tables;
	uint64_t slot_bytes;
	uint64_t total_bytes;
	uint32_t generation;		/* futex word: +1 on every publication (atomic) */
	uint32_t current_slot;		/* newest published slot (atomic) */
	uint32_t superseded;		/* 1: never written again; a new region comes on the socket */
	uint32_t reserved0;
	struct sky_shm_table tables[SKY_SHM_MAX_TABLES];
	/* View regions: max_views of them (0 until a view is first added,
	 * then SKY_SHM_MAX_VIEWS: a new region), view_stride bytes apart, each
	 * room for a volume or a panorama. */
	uint32_t max_views;
	uint32_t reserved1;
	uint64_t view_offset;		/* from the start of a slot */
	uint64_t view_stride;
};

/* The slot checksum (PROTOCOL.md, "Checksum"): FNV-1a 64 over 64-bit
 * native-endian words, first the slot's state, then its clouds (layout 7),
 * then every valid table in id order, then, when n_views > 0,
 * views[0 .. n_views) and each valid view's volume (form volume) or panorama (form panorama: its panorama.bytes at
 * panorama.offset, once per view even where views share it) in index
 * order. words counts 8-byte words; start a checksum with SKY_SHM_CHECKSUM_SEED. */
#define SKY_SHM_CHECKSUM_SEED 0xcbf29ce484222325ull
static inline uint64_t sky_shm_checksum_words(uint64_t h, const void *data, uint64_t words)
{
	const unsigned char *p = (const unsigned char *)data;
	for (uint64_t i = 0; i < words; i++) {
		uint64_t w;
		__builtin_memcpy(&w, p + 8 * i, 8);
		h ^= w;
		h *= 0x100000001b3ull;
	}
	return h;
}

#endif
