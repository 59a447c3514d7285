/* rvk.h - skyrender's Vulkan side: a device, an offscreen target, the sky
 * tables as images (two sets, so that frames keep drawing from one while a
 * new generation uploads into the other), and one frame drawn and read back.
 *
 * Every function returns 0 or -errno and, on failure, writes one line into
 * err saying which call failed and why. Nothing here prints or exits.
 */
#ifndef SKYRENDER_RVK_H
#define SKYRENDER_RVK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "sky.h"

struct rvk;

enum rvk_projection {
	RVK_PERSPECTIVE = 0,		/* sky_render's SKY_PROJECTION_PERSPECTIVE */
	RVK_FISHEYE = 1,		/* sky_render's SKY_PROJECTION_FISHEYE (domemaster) */
};

/* The camera of a whole wall and the one tile of it this process draws: the
 * wall is cols * width by rows * height pixels, seen by one camera (yaw,
 * pitch, vertical field of view of the whole wall), and tile (col, row)
 * is its sub-rectangle, so that neighbouring tiles continue each other
 * pixel for pixel. A 1 x 1 grid is a plain camera. */
struct rvk_camera {
	enum rvk_projection projection;
	uint32_t width, height;		/* the tile, pixels */
	uint32_t cols, rows;		/* the grid, >= 1 */
	uint32_t col, row;		/* this tile, col < cols, row < rows */
	double yaw_deg, pitch_deg;	/* perspective: the axis; fisheye: yaw is the front */
	double vfov_deg;		/* perspective: the wall's vertical field of view */
};

struct rvk_options {
	const char *device;		/* index or name substring; NULL: $SKYD_DEVICE, else the best */
	struct rvk_camera camera;
	bool terrain;			/* draw the height field */
	unsigned disk_flags;		/* enum sky_sample_flags: the sun and moon disks */
	double terrain_albedo;		/* the ground's reflectance, [0, 1] */
	int cloud_steps;		/* the cloud march's steps (the quality knob); 0: no clouds */
};

/* Opens a device and builds the target, the pipelines and the terrain mesh.
 * -ENODEV without a Vulkan device. The caller frees *ret with rvk_free(). */
int rvk_new(const struct rvk_options *o, char *err, size_t err_size, struct rvk **ret);

/* Waits for the device and frees everything; NULL is a no-op. */
void rvk_free(struct rvk *r);

/* The device's name, valid until rvk_free(). */
const char *rvk_device_name(const struct rvk *r);

/* Aerial-perspective textures a frame reads: one for a perspective tile
 * or a dome master (a volume, or a panorama of the eye point: the GLSL
 * library's sky_aerial_dir reads either); four volumes for a dome master
 * of volumes, each a quarter of the horizon (volume k faces yaw + 90 k
 * degrees, 90 degrees wide). */
#define RVK_MAX_AERIAL 4

/* What one upload takes from a stable view (sky_view_begin() or
 * sky_snapshot()): the tables as sky_gpu_tables() describes them, the
 * aerial textures to draw with (views' volumes or panoramas,
 * sky_gpu_view_table(), or the state's aerial table: each its own format
 * and size) and for each the library's uniforms of the same slot with
 * that texture's camera and form (sky_gpu_state()). */
struct rvk_upload {
	const struct sky_gpu_table *tables;	/* [SKY_SHM_MAX_TABLES] */
	uint32_t n_aerial;			/* 1 or RVK_MAX_AERIAL */
	const struct sky_gpu_table *aerial[RVK_MAX_AERIAL];	/* NULL or not present: none */
	bool aerial_is_view[RVK_MAX_AERIAL];	/* a view's volume or panorama: its own
						 * change generations */
	const struct sky_gpu_state *state[RVK_MAX_AERIAL];
	uint32_t generation;			/* the view's */
	double ambient_lx[3];			/* sky_sample_ambient() of the view */
	const struct sky_shm_clouds *clouds;	/* the slot's cloud field; NULL: none */
};

/* Starts uploading into the set of images frames are not drawing from:
 * each table (the aerial volume among them) whose changed_generation
 * differs from what that set holds, and the uniforms. The texels are copied out of the
 * view before this returns, so the caller may check sky_view_end() right
 * after: when it says torn, call rvk_cancel_upload() and begin again. A set
 * still uploading is waited for and replaced. */
int rvk_upload(struct rvk *r, const struct rvk_upload *u, char *err, size_t err_size);

/* Forgets which table generations the images hold, so that the next
 * upload sends every table: after a new mapping (a layout change or a
 * restarted skyd, whose generations may repeat the old one's numbers).
 * The images themselves stay and frames keep drawing from them. */
void rvk_forget_tables(struct rvk *r);

/* Forgets the upload started last (its texels were torn). */
void rvk_cancel_upload(struct rvk *r);

/* Draws one frame and reads it back: width * height RGBA floats, linear
 * radiance (cd/m2), rows top to bottom, into *ret_rgba (owned by r, valid
 * until the next call on r); *ret_generation the generation it drew. A
 * finished upload becomes the drawn set first; an unfinished one is left
 * running and the previous set is drawn. -EAGAIN before any upload. */
int rvk_draw(struct rvk *r, const float **ret_rgba, uint64_t *ret_generation, char *err,
	     size_t err_size);

#endif
