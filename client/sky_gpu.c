/* sky_gpu.c - libsky for render clients that sample the tables on their own
 * GPU: each table's format, extent and texels for upload, with the
 * generation its contents last changed in, and the uniforms of the GLSL
 * library (proto/glsl/sky.glsl). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sky_internal.h"
#include "skysample.h"

/* What identifies a table's contents: its shape, format and scale, then
 * its bytes (a whole number of 8-byte words: texels are 8 or 16 bytes). */
static uint64_t table_hash(const struct skysample_table *t, uint64_t bytes)
{
	uint64_t shape[3] = { (uint64_t)t->format << 32 | (uint32_t)t->rgb_scale_log2,
			      (uint64_t)t->width << 32 | t->height, t->depth };
	uint64_t h = sky_shm_checksum_words(SKY_SHM_CHECKSUM_SEED, shape, 3);
	return sky_shm_checksum_words(h, t->texels, bytes / 8);
}

/* True when v is a zero-copy view of c's mapping whose slot was rewritten
 * since sky_view_begin(); a snapshot's slot (the caller's copy) never is. */
static bool torn(const sky_client *c, const struct sky_view *v)
{
	const struct sky_shm_header *h = c->map;
	if (!h || v->header != h || v->slot_index >= h->n_slots)
		return false;
	const unsigned char *slot = (const unsigned char *)h + h->header_bytes +
				    (uint64_t)v->slot_index * h->slot_bytes;
	if ((const void *)slot != v->slot_base)
		return false;
	return !sky_view_end(c, v);
}

/* Fills ret (zeroed by the caller) for table t of view v. */
static void describe(const struct sky_view *v, const struct skysample_table *t,
		     struct sky_gpu_table *ret)
{
	bool half = t->format == SKY_FORMAT_RGBA16F;
	ret->present = 1;
	ret->format = t->format;
	ret->vk_format = half ? SKY_VK_FORMAT_R16G16B16A16_SFLOAT : SKY_VK_FORMAT_R32G32B32A32_SFLOAT;
	ret->width = t->width;
	ret->height = t->height;
	ret->depth = t->depth;
	ret->texel_bytes = half ? 8 : 16;
	ret->row_pitch_bytes = (uint64_t)t->width * ret->texel_bytes;
	ret->slice_pitch_bytes = ret->row_pitch_bytes * t->height;
	ret->bytes = ret->slice_pitch_bytes * t->depth;
	ret->texels = t->texels;
	ret->rgb_scale_log2 = half ? t->rgb_scale_log2 : 0;
	const unsigned char *m = (const unsigned char *)v->header, *p = t->texels;
	ret->map_offset = p > m && (uint64_t)(p - m) < v->header->total_bytes ? (uint64_t)(p - m) : 0;
}

int sky_gpu_tables(sky_client *c, const struct sky_view *v,
		   struct sky_gpu_table ret_tables[SKY_SHM_MAX_TABLES])
{
	struct sky_gpu_table out[SKY_SHM_MAX_TABLES];
	struct sky_gpu_seen seen[SKY_SHM_MAX_TABLES];
	int changed = 0;

	if (!c || !v || !v->header || !v->slot || !v->slot_base || !ret_tables)
		return -EINVAL;
	if (c->gpu_map != v->header) {
		memset(c->gpu_seen, 0, sizeof(c->gpu_seen));
		memset(c->gpu_views, 0, sizeof(c->gpu_views));
		c->gpu_map = v->header;
	}
	memcpy(seen, c->gpu_seen, sizeof(seen));
	memset(out, 0, sizeof(out));
	for (uint32_t id = 0; id < SKY_SHM_MAX_TABLES; id++) {
		struct skysample_table t;
		out[id].id = id;
		if (!(v->valid_tables & SKY_TABLE_BIT(id)) ||
		    skysample_table_from_slot(v->header, v->slot_base, id, &t) < 0) {
			seen[id].known = false;
			continue;
		}
		describe(v, &t, &out[id]);
		struct sky_gpu_seen *s = &seen[id];
		if (!s->known || s->generation != v->generation) {
			uint64_t h = table_hash(&t, out[id].bytes);
			if (!s->known || h != s->hash)
				s->changed = v->generation;
			s->known = true;
			s->hash = h;
			s->generation = v->generation;
		}
		out[id].changed_generation = s->changed;
		if (s->changed == v->generation)
			changed |= (int)SKY_TABLE_BIT(id);
	}
	/* A hash of a slot rewritten under us would record contents that were
	 * never published. */
	if (torn(c, v))
		return -EAGAIN;
	memcpy(c->gpu_seen, seen, sizeof(seen));
	memcpy(ret_tables, out, sizeof(out));
	return changed;
}

/* The record of what view name's volume held, reusing the record of a
 * name the slot no longer has when name is new. */
static struct sky_gpu_seen_view *seen_view(sky_client *c, const struct sky_view *v, const char *name)
{
	struct sky_gpu_seen_view *free_one = NULL;
	for (uint32_t i = 0; i < SKY_SHM_MAX_VIEWS; i++) {
		struct sky_gpu_seen_view *e = &c->gpu_views[i];
		if (strncmp(e->name, name, SKY_SHM_VIEW_NAME_MAX) == 0)
			return e;
		bool live = false;
		for (uint32_t k = 0; e->name[0] && k < v->slot->n_views && k < SKY_SHM_MAX_VIEWS; k++)
			live |= strncmp(v->slot->views[k].name, e->name, SKY_SHM_VIEW_NAME_MAX) == 0;
		if (!live && !free_one)
			free_one = e;
	}
	if (free_one) {
		memset(free_one, 0, sizeof(*free_one));
		snprintf(free_one->name, sizeof(free_one->name), "%s", name);
	}
	return free_one;
}

/* A hash of the panorama of view vw already taken in v's generation for
 * another view on the same eye point (same offset and size): views of form
 * panorama share their eye point's texels, and a wall of eight would
 * otherwise hash the same bytes eight times. */
static bool shared_hash(const sky_client *c, const struct sky_view *v, const struct sky_shm_view *vw,
			uint64_t *ret_hash)
{
	if (vw->form != SKY_VIEW_PANORAMA)
		return false;
	for (uint32_t i = 0; i < SKY_SHM_MAX_VIEWS; i++) {
		const struct sky_gpu_seen_view *e = &c->gpu_views[i];
		if (!e->name[0] || !e->seen.known || e->seen.generation != v->generation)
			continue;
		for (uint32_t k = 0; k < v->slot->n_views && k < SKY_SHM_MAX_VIEWS; k++) {
			const struct sky_shm_view *o = &v->slot->views[k];
			if (o != vw && strncmp(o->name, e->name, SKY_SHM_VIEW_NAME_MAX) == 0 &&
			    o->form == SKY_VIEW_PANORAMA && (v->slot->valid_views & (1u << k)) &&
			    o->panorama.offset == vw->panorama.offset &&
			    o->panorama.bytes == vw->panorama.bytes) {
				*ret_hash = e->seen.hash;
				return true;
			}
		}
	}
	return false;
}

int sky_gpu_view_table(sky_client *c, const struct sky_view *v, const char *name,
		       struct sky_gpu_table *ret_table)
{
	const struct sky_shm_view *vw;
	struct skysample_table t;
	struct sky_gpu_table out;

	if (!c || !v || !v->header || !v->slot || !v->slot_base || !name || !ret_table ||
	    strlen(name) >= SKY_SHM_VIEW_NAME_MAX)
		return -EINVAL;
	int r = skysample_view_from_slot(v->header, v->slot_base, name, &t, &vw);
	if (r < 0)
		return r;
	if (c->gpu_map != v->header) {
		memset(c->gpu_seen, 0, sizeof(c->gpu_seen));
		memset(c->gpu_views, 0, sizeof(c->gpu_views));
		c->gpu_map = v->header;
	}
	memset(&out, 0, sizeof(out));
	out.id = SKY_TABLE_AERIAL;
	describe(v, &t, &out);
	struct sky_gpu_seen_view *e = seen_view(c, v, name);
	struct sky_gpu_seen seen = e ? e->seen : (struct sky_gpu_seen){ 0 };
	if (!seen.known || seen.generation != v->generation) {
		uint64_t h;
		if (!shared_hash(c, v, vw, &h))
			h = table_hash(&t, out.bytes);
		if (!seen.known || h != seen.hash)
			seen.changed = v->generation;
		seen.known = true;
		seen.hash = h;
		seen.generation = v->generation;
	}
	if (torn(c, v))
		return -EAGAIN;
	if (e)
		e->seen = seen;
	out.changed_generation = seen.changed;
	*ret_table = out;
	return seen.changed == v->generation;
}

static void put4(float ret[4], const double xyz[3], double w)
{
	ret[0] = (float)xyz[0];
	ret[1] = (float)xyz[1];
	ret[2] = (float)xyz[2];
	ret[3] = (float)w;
}

int sky_gpu_state(const struct sky_view *v, const char *view_name, struct sky_gpu_state *ret_state)
{
	struct sky_gpu_state g;
	if (!v || !v->header || !v->slot || !ret_state)
		return -EINVAL;
	const struct sky_shm_state *st = &v->slot->state;
	double alt = st->altitude_km, vfov = st->camera_vfov_rad, aspect = st->camera_aspect;
	const double *fwd = st->camera_forward, *right = st->camera_right, *up = st->camera_up;
	const struct sky_shm_view *vw = NULL;
	if (view_name) {
		for (uint32_t i = 0; i < v->slot->n_views && i < SKY_SHM_MAX_VIEWS; i++)
			if (strncmp(v->slot->views[i].name, view_name, SKY_SHM_VIEW_NAME_MAX) == 0)
				vw = &v->slot->views[i];
		if (!vw)
			return -ENOENT;
		alt = vw->altitude_km;
		vfov = vw->camera_vfov_rad;
		aspect = vw->camera_aspect;
		fwd = vw->camera_forward;
		right = vw->camera_right;
		up = vw->camera_up;
	}
	memset(&g, 0, sizeof(g));
	put4(g.sun, st->sun_direction, st->sun_angular_radius_rad);
	put4(g.sun_illuminance_lx, st->sun_illuminance_lx, 0.0);
	put4(g.moon, st->moon_direction, st->moon_angular_radius_rad);
	put4(g.moon_illuminance_lx, st->moon_illuminance_lx, 0.0);
	double planet[3] = { st->bottom_radius_km, st->top_radius_km, st->altitude_km };
	put4(g.planet, planet, 0.0);
	double hc = skymap_horizon_cos(st->bottom_radius_km, st->altitude_km);
	double horizon[3] = { hc, st->bottom_radius_km / (st->bottom_radius_km + fmax(st->altitude_km, 0.0)),
			      acos(hc) };
	put4(g.horizon, horizon, 0.0);
	/* The sky's four tables: the cloud tables are float32, never scaled. */
	for (uint32_t id = 0; id <= SKY_TABLE_AERIAL; id++) {
		struct skysample_table t;
		bool half = skysample_table_from_slot(v->header, v->slot_base, id, &t) == 0 &&
			    t.format == SKY_FORMAT_RGBA16F;
		g.rgb_scale[id] = half ? (float)ldexp(1.0, st->rgb_scale_log2[id]) : 1.0f;
	}
	double aerial[3] = { st->aerial_range_km, st->aerial_squared ? 1.0 : 0.0, tan(0.5 * vfov) };
	put4(g.aerial, aerial, aspect);
	put4(g.camera_forward, fwd, 0.0);
	put4(g.camera_right, right, 0.0);
	put4(g.camera_up, up, alt);
	if (vw && vw->form == SKY_VIEW_PANORAMA) {
		const struct sky_shm_panorama *p = &vw->panorama;
		double pan[3] = { p->azimuth0_rad, p->azimuth_step_rad, p->row0 };
		double grid[3] = { p->horizon_rad, p->width, p->height };
		put4(g.panorama, pan, p->row_step);
		put4(g.panorama_grid, grid, p->full_circle ? 2.0 : 1.0);
	}
	*ret_state = g;
	return 0;
}
