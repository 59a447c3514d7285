/* aplan.h - where a state's aerial perspective goes: which cameras (the
 * state's camera, then its views) get a volume of their own, which eye
 * points are marched once as a panorama, and the directions of each
 * panorama. Pure geometry of the state, shared by the engine, which
 * computes the volumes and panoramas, and the publisher, which places them
 * in the slot (proto/skyproto.h, struct sky_shm_panorama). */
#ifndef SKYD_APLAN_H
#define SKYD_APLAN_H

#include <stdbool.h>
#include <stdint.h>

#include "skyproto.h"
#include "state.h"

/* The state's camera and STATE_MAX_VIEWS views. */
#define APLAN_CAMERAS (1 + STATE_MAX_VIEWS)

/* A camera as the shaders see it: its eye's altitude and horizontal
 * position, its frame, and the lights in its eye's local frame. */
struct aplan_camera {
	double h_km, east_km, north_km;
	/* The eye's local axes (east, north, up: rows) and its ground point in
	 * the observer's frame, km from the ground under the observer. */
	double site[3][3], ground_km[3];
	double fwd[3], right[3], up[3];
	double tan_half, aspect;
	double sun[3], moon[3];
};

/* One eye point's panorama: m0 = (first column's azimuth, azimuth step,
 * row 0's x, row step), m1 = (the eye's horizon elevation, width, height,
 * 1 for the full circle), as aerial.comp marches it and
 * skymap_panorama_uv reads it. */
struct aplan_panorama {
	int32_t view;			/* the first view of form panorama on its eye
					 * point (its slot region holds the texels),
					 * -1: scratch, only resampled into volumes */
	uint32_t leader;		/* the first camera on the eye point */
	float m0[4], m1[4];
};

struct aplan {
	uint32_t n_cameras;		/* 1 + the state's views */
	uint32_t n_volumes;		/* volumes, the state's camera's first */
	uint32_t n_panoramas;		/* published ones first, then scratch */
	uint32_t width, height, depth;	/* one panorama's texels */
	struct aplan_camera cam[APLAN_CAMERAS];
	int32_t volume[APLAN_CAMERAS];	/* camera c's volume, -1: it reads a panorama */
	int32_t panorama[APLAN_CAMERAS];	/* the panorama c reads or is resampled
						 * from, -1: its volume is marched */
	struct aplan_panorama pano[APLAN_CAMERAS];
};

/* The plan of s. share: cameras of form volume on one eye point are
 * resampled from its panorama (the default), else each is marched (the
 * reference, tests/numerical/test_views.c); views of form panorama read their eye
 * point's panorama either way. Volumes and published panoramas are
 * numbered the same either way. */
void aplan_make(const struct sky_state *s, bool share, struct aplan *ret);
/* aplan_make with the state's lights as its owner computed them
 * (state_lights_of): the engine's and the publisher's plans of one state
 * see the same vectors. */
void aplan_make_lit(const struct sky_state *s, const struct state_lights *lights, bool share,
		    struct aplan *ret);

/* The columns (the stored ones) and rows of every panorama of s, which
 * depend on its aerial table's size only. */
void aplan_panorama_shape(const struct sky_state *s, uint32_t *ret_width, uint32_t *ret_height);

/* Texels of one panorama of the plan. */
static inline uint64_t aplan_panorama_texels(const struct aplan *p)
{
	return (uint64_t)p->width * p->height * p->depth;
}

/* Bytes of p's published panoramas (those a view of form panorama reads,
 * numbered first), float32 RGBA. */
uint64_t aplan_published_bytes(const struct aplan *p);

/* Panorama k of p as the slot describes it, its texels at offset (from
 * the start of the slot): the mapping's floats, exactly. */
void aplan_describe(const struct aplan *p, int32_t k, uint64_t offset, struct sky_shm_panorama *ret);

#endif
