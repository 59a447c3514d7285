/* skysample.h - the CPU sampler of the published tables, shared by libsky and
 * the daemon's `sample` verbs so that both give the same numbers bit for bit.
 *
 * Header-only, double precision, depends on <math.h>, <stdint.h>, <string.h>,
 * skyproto.h (formats, state) and skymap.h (the uv mappings). Nothing here
 * allocates, blocks or keeps state; every function is thread-safe as long
 * as the memory it reads does not change under it (the caller's business:
 * see the slot sequence protocol in skyproto.h).
 *
 * Conventions: directions in the observer's east-north-up frame, azimuth
 * eastward from north, elevation above the astronomical horizon, radians.
 * Sampling is bilinear between texel centres, texel i of n centred at
 * (i + 0.5) / n; the sky-view longitude wraps, every other axis clamps.
 * The aerial perspective volume is indexed by screen position (u right,
 * v up, in [0, 1]; froxel (i, j) centred at ((i + 0.5) / W, (j + 0.5) / H))
 * and by the distance along the view ray through skymap_aerial_slice();
 * a view's panorama (struct sky_shm_panorama) by the direction's azimuth
 * and elevation through skymap_panorama_uv() and the same slices, its RGB
 * the logarithm of the radiance (skysample_panorama).
 */
#ifndef SKYD_SKYSAMPLE_H
#define SKYD_SKYSAMPLE_H

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "skymap.h"
#include "skyproto.h"

/* One table as laid out in a slot (or a copy of one). */
struct skysample_table {
	const void *texels;		/* RGBA, rows bottom-up in v, slices stacked */
	uint32_t format;		/* enum sky_shm_format */
	uint32_t width, height, depth;
	int32_t rgb_scale_log2;		/* RGB = stored * 2^this (the slot state's) */
};

/* IEEE binary16 -> double, exact for every input (subnormals, inf, NaN). */
static inline double skysample_half(uint16_t h)
{
	int e = (h >> 10) & 0x1f;
	double m = h & 0x3ff, x;
	if (e == 0)
		x = ldexp(m, -24);
	else if (e == 31)
		x = m ? NAN : INFINITY;
	else
		x = ldexp(m + 1024.0, e - 25);
	return (h & 0x8000) ? -x : x;
}

/* Texel (i, j, k) as four doubles, RGB unscaled (times 2^rgb_scale_log2,
 * exact); indices must be in range. */
static inline void skysample_texel(const struct skysample_table *t, uint32_t i, uint32_t j,
				   uint32_t k, double ret_rgba[4])
{
	size_t idx = (((size_t)k * t->height + j) * t->width + i) * 4;
	if (t->format == SKY_FORMAT_RGBA16F) {
		const uint16_t *p = (const uint16_t *)t->texels + idx;
		for (int c = 0; c < 4; c++)
			ret_rgba[c] = skysample_half(p[c]);
		for (int c = 0; c < 3 && t->rgb_scale_log2; c++)
			ret_rgba[c] = ldexp(ret_rgba[c], t->rgb_scale_log2);
	} else {
		const float *p = (const float *)t->texels + idx;
		for (int c = 0; c < 4; c++)
			ret_rgba[c] = p[c];
	}
}

/* Splits a texture coordinate into two texel indices and the weight of the
 * second; wrap selects the periodic axis. */
static inline void skysample_axis(double u, uint32_t n, int wrap, uint32_t *ret_i0,
				  uint32_t *ret_i1, double *ret_f)
{
	double x = u * n - 0.5;
	if (!(x == x))			/* NaN reads as the first texel, never out of range */
		x = 0.0;
	double fl = floor(x);
	double f = x - fl;
	if (wrap) {
		double m = fmod(fl, (double)n);
		if (m < 0.0)
			m += n;
		uint32_t i0 = (uint32_t)m;
		*ret_i0 = i0 < n ? i0 : 0;
		*ret_i1 = *ret_i0 + 1 < n ? *ret_i0 + 1 : 0;
		*ret_f = f;
		return;
	}
	if (fl < 0.0) {
		*ret_i0 = *ret_i1 = 0;
		*ret_f = 0.0;
	} else if (fl >= n - 1) {
		*ret_i0 = *ret_i1 = n - 1;
		*ret_f = 0.0;
	} else {
		*ret_i0 = (uint32_t)fl;
		*ret_i1 = *ret_i0 + 1;
		*ret_f = f;
	}
}

/* Bilinear sample of slice k at (u, v). */
static inline void skysample_bilinear(const struct skysample_table *t, double u, double v,
				      uint32_t k, int wrap_u, double ret_rgba[4])
{
	uint32_t i0, i1, j0, j1;
	double fu, fv, a[4], b[4], c[4], d[4];
	skysample_axis(u, t->width, wrap_u, &i0, &i1, &fu);
	skysample_axis(v, t->height, 0, &j0, &j1, &fv);
	skysample_texel(t, i0, j0, k, a);
	skysample_texel(t, i1, j0, k, b);
	skysample_texel(t, i0, j1, k, c);
	skysample_texel(t, i1, j1, k, d);
	for (int n = 0; n < 4; n++) {
		double lo = a[n] + fu * (b[n] - a[n]);
		double hi = c[n] + fu * (d[n] - c[n]);
		ret_rgba[n] = lo + fv * (hi - lo);
	}
}

/* Finds table id in the header's directory and points ret at it inside the
 * slot that starts at slot_base, with the slot's scale of the table.
 * -ENOENT when the layout has no such table. The directory is assumed
 * checked (skysample_check_layout). */
static inline int skysample_table_from_slot(const struct sky_shm_header *hdr,
					    const void *slot_base, uint32_t id,
					    struct skysample_table *ret)
{
	for (uint32_t n = 0; n < hdr->n_tables && n < SKY_SHM_MAX_TABLES; n++) {
		const struct sky_shm_table *d = &hdr->tables[n];
		if (d->id != id)
			continue;
		ret->texels = (const unsigned char *)slot_base + d->offset;
		ret->format = d->format;
		ret->width = d->width;
		ret->height = d->height;
		ret->depth = d->depth;
		ret->rgb_scale_log2 = ((const struct sky_shm_slot *)slot_base)->state.rgb_scale_log2[id];
		return 0;
	}
	return -ENOENT;
}

/* Checks a header read from a peer before anything indexes with it: magic,
 * versions, slot geometry inside total_bytes (itself <= map_bytes), each
 * table inside a slot with bytes = w * h * d * texel_bytes. 0 or -EPROTO
 * (-EPROTONOSUPPORT for a version this code does not know). */
static inline int skysample_check_layout(const struct sky_shm_header *hdr, uint64_t map_bytes)
{
	if (map_bytes < sizeof(*hdr) || hdr->magic != SKY_SHM_MAGIC)
		return -EPROTO;
	if (hdr->layout_version != SKY_SHM_LAYOUT_VERSION || hdr->uv_mapping_version != SKYMAP_VERSION)
		return -EPROTONOSUPPORT;
	if (hdr->n_slots < SKY_SHM_MIN_SLOTS || hdr->n_slots > 1024 ||
	    hdr->n_tables > SKY_SHM_MAX_TABLES || hdr->header_bytes < sizeof(*hdr) ||
	    hdr->slot_bytes < sizeof(struct sky_shm_slot) || hdr->total_bytes > map_bytes ||
	    hdr->slot_bytes > hdr->total_bytes ||
	    hdr->header_bytes % _Alignof(struct sky_shm_slot) ||
	    hdr->slot_bytes % _Alignof(struct sky_shm_slot))
		return -EPROTO;	/* a slot must be where its fields can be read */
	if (hdr->header_bytes + (uint64_t)hdr->n_slots * hdr->slot_bytes > hdr->total_bytes)
		return -EPROTO;
	for (uint32_t n = 0; n < hdr->n_tables; n++) {
		const struct sky_shm_table *d = &hdr->tables[n];
		uint32_t tb = d->format == SKY_FORMAT_RGBA32F ? 16 : d->format == SKY_FORMAT_RGBA16F ? 8 : 0;
		if (!tb || d->texel_bytes != tb || d->id >= SKY_SHM_MAX_TABLES || !d->width ||
		    !d->height || !d->depth || d->width > 65536 || d->height > 65536 ||
		    d->depth > 65536)
			return -EPROTO;
		uint64_t bytes = (uint64_t)d->width * d->height * d->depth * tb;
		if (d->bytes != bytes || d->offset < sizeof(struct sky_shm_slot) ||
		    d->offset > hdr->slot_bytes || bytes > hdr->slot_bytes - d->offset ||
		    d->offset % 8)
			return -EPROTO;
	}
	if (hdr->max_views > SKY_SHM_MAX_VIEWS)
		return -EPROTO;
	if (hdr->max_views) {
		const struct sky_shm_table *a = NULL;
		for (uint32_t n = 0; n < hdr->n_tables; n++)
			if (hdr->tables[n].id == SKY_TABLE_AERIAL)
				a = &hdr->tables[n];
		if (!a || hdr->view_stride < a->bytes || hdr->view_offset % 8 ||
		    hdr->view_offset < sizeof(struct sky_shm_slot) ||
		    hdr->view_offset > hdr->slot_bytes ||
		    hdr->view_stride * hdr->max_views > hdr->slot_bytes - hdr->view_offset)
			return -EPROTO;
	}
	return 0;
}

/* 0 when view v's panorama (form SKY_VIEW_PANORAMA) lies inside a slot of
 * the header's slot_bytes, after the slot's own struct, 8-byte aligned,
 * with bytes = width * height * depth * 16 and every size in [1, 65536];
 * else -EPROTO. The entry comes from a peer: nothing indexes with it
 * before this holds. */
static inline int skysample_check_panorama(const struct sky_shm_header *hdr,
					   const struct sky_shm_view *v)
{
	const struct sky_shm_panorama *p = &v->panorama;
	if (!p->width || !p->height || !p->depth || p->width > 65536 || p->height > 65536 ||
	    p->depth > 65536)
		return -EPROTO;
	uint64_t bytes = (uint64_t)p->width * p->height * p->depth * 16u;
	if (p->bytes != bytes || p->offset % 8 || p->offset < sizeof(struct sky_shm_slot) ||
	    p->offset > hdr->slot_bytes || bytes > hdr->slot_bytes - p->offset)
		return -EPROTO;
	return 0;
}

/* Finds the view called name in a slot at slot_base (layout checked) and
 * points ret at its aerial perspective; ret_view (may be NULL) gets its
 * entry, whose form says which: a volume (SKY_VIEW_VOLUME, the aerial
 * table's format, sizes and scale at view_offset + i * view_stride;
 * skysample_aerial) or its eye point's panorama (SKY_VIEW_PANORAMA,
 * RGBA32F at panorama.offset with the panorama's sizes and scale 0;
 * skysample_panorama with the entry's panorama). -ENOENT if the slot has
 * no such view, -ENODATA if it is not valid in this slot, -EPROTO if the
 * entry's form is unknown or its panorama fails skysample_check_panorama. */
static inline int skysample_view_from_slot(const struct sky_shm_header *hdr,
					   const void *slot_base, const char *name,
					   struct skysample_table *ret,
					   const struct sky_shm_view **ret_view)
{
	const struct sky_shm_slot *slot = (const struct sky_shm_slot *)slot_base;
	struct skysample_table aerial;

	for (uint32_t i = 0; i < slot->n_views && i < hdr->max_views; i++) {
		const struct sky_shm_view *v = &slot->views[i];
		if (__builtin_strncmp(v->name, name, SKY_SHM_VIEW_NAME_MAX) != 0)
			continue;
		if (!(slot->valid_views & (1u << i)))
			return -ENODATA;
		if (v->form == SKY_VIEW_PANORAMA) {
			if (skysample_check_panorama(hdr, v) < 0)
				return -EPROTO;
			ret->texels = (const unsigned char *)slot_base + v->panorama.offset;
			ret->format = SKY_FORMAT_RGBA32F;
			ret->width = v->panorama.width;
			ret->height = v->panorama.height;
			ret->depth = v->panorama.depth;
			ret->rgb_scale_log2 = 0;
		} else if (v->form == SKY_VIEW_VOLUME) {
			if (skysample_table_from_slot(hdr, slot_base, SKY_TABLE_AERIAL, &aerial) < 0)
				return -ENOENT;
			*ret = aerial;
			ret->texels = (const unsigned char *)slot_base + hdr->view_offset +
				      i * hdr->view_stride;
		} else {
			return -EPROTO;
		}
		if (ret_view)
			*ret_view = v;
		return 0;
	}
	return -ENOENT;
}

/* The slot checksum of skyproto.h over a slot (or a copy of one) at
 * slot_base: the state, then each valid table in id order, then the views'
 * entries and each valid view's volume or panorama in index order (a
 * panorama once per view, also where views share it). A panorama that
 * fails skysample_check_panorama adds nothing, so the sum cannot match. */
static inline uint64_t skysample_slot_checksum(const struct sky_shm_header *hdr,
					       const void *slot_base)
{
	const struct sky_shm_slot *slot = (const struct sky_shm_slot *)slot_base;
	const unsigned char *base = (const unsigned char *)slot_base;
	uint64_t c = sky_shm_checksum_words(SKY_SHM_CHECKSUM_SEED, &slot->state,
					    sizeof(slot->state) / 8);
	c = sky_shm_checksum_words(c, &slot->clouds, sizeof(slot->clouds) / 8);
	for (uint32_t id = 0; id < SKY_SHM_MAX_TABLES; id++) {
		if (!(slot->valid_tables & (1u << id)))
			continue;
		for (uint32_t n = 0; n < hdr->n_tables && n < SKY_SHM_MAX_TABLES; n++)
			if (hdr->tables[n].id == id)
				c = sky_shm_checksum_words(c, base + hdr->tables[n].offset,
							   hdr->tables[n].bytes / 8);
	}
	if (!slot->n_views || slot->n_views > SKY_SHM_MAX_VIEWS)
		return c;
	c = sky_shm_checksum_words(c, slot->views, slot->n_views * sizeof(slot->views[0]) / 8);
	for (uint32_t i = 0; i < slot->n_views && i < hdr->max_views; i++) {
		const struct sky_shm_view *v = &slot->views[i];
		struct skysample_table t;
		if (!(slot->valid_views & (1u << i)))
			continue;
		if (v->form == SKY_VIEW_PANORAMA) {
			if (skysample_check_panorama(hdr, v) == 0)
				c = sky_shm_checksum_words(c, base + v->panorama.offset,
							   v->panorama.bytes / 8);
		} else if (v->form == SKY_VIEW_VOLUME &&
			   skysample_table_from_slot(hdr, slot_base, SKY_TABLE_AERIAL, &t) == 0) {
			c = sky_shm_checksum_words(c, base + hdr->view_offset + i * hdr->view_stride,
						   (uint64_t)t.width * t.height * t.depth *
						   (t.format == SKY_FORMAT_RGBA16F ? 8 : 16) / 8);
		}
	}
	return c;
}

/* Transmittance to the top of the atmosphere from altitude_km along the
 * cosine of the zenith angle mu, for a ray that does not meet the ground
 * (the table holds nothing else: a caller asking below the horizon gets the
 * horizon's value). RGB, in [0, 1]. */
static inline void skysample_transmittance(const struct skysample_table *t,
					   const struct sky_shm_state *st, double altitude_km,
					   double mu, double ret_rgb[3])
{
	double u, v, px[4];
	skymap_transmittance_uv(st->bottom_radius_km, st->top_radius_km, altitude_km, mu, t->width,
				t->height, &u, &v);
	skysample_bilinear(t, u, v, 0, 0, px);
	for (int c = 0; c < 3; c++)
		ret_rgb[c] = px[c];
}

/* Sky radiance from the sky-view table toward (elevation, azimuth), at the
 * observer's altitude in the state; no sun or moon disk. RGB radiance, in
 * cd/m2 per channel when the illuminances are in lx. */
static inline void skysample_sky(const struct skysample_table *t, const struct sky_shm_state *st,
				 double elevation_rad, double azimuth_rad, double ret_rgb[3])
{
	double u, v, px[4];
	double hc = skymap_horizon_cos(st->bottom_radius_km, st->altitude_km);
	skymap_skyview_uv(hc, 0.5 * SKYMAP_PI - elevation_rad, azimuth_rad, t->height, &u, &v);
	skysample_bilinear(t, u, v, 0, 1, px);
	for (int c = 0; c < 3; c++)
		ret_rgb[c] = px[c];
}

/* Aerial perspective at screen position (screen_u, screen_v) of the camera
 * in the state, distance_km along the view ray: in-scattered RGB radiance
 * and the mean transmittance. Depth 0 is (0, 1); beyond the last slice the
 * last slice holds. Between slices and between the camera and slice 0 the
 * value is linear in the slice coordinate. */
static inline void skysample_aerial(const struct skysample_table *t,
				    const struct sky_shm_state *st, double screen_u,
				    double screen_v, double distance_km, double ret_rgb[3],
				    double *ret_transmittance)
{
	double w = skymap_aerial_slice(distance_km, t->depth, st->aerial_range_km,
				       st->aerial_squared != 0);
	double a[4], b[4] = { 0.0, 0.0, 0.0, 1.0 }, f;
	if (!(w == w))
		w = -1.0;
	if (w <= 0.0) {
		skysample_bilinear(t, screen_u, screen_v, 0, 0, a);
		f = w + 1.0;		/* 0 at the camera, 1 at the far edge of slice 0 */
		if (f < 0.0)
			f = 0.0;
	} else if (w >= t->depth - 1) {
		skysample_bilinear(t, screen_u, screen_v, t->depth - 1, 0, a);
		f = 1.0;
	} else {
		uint32_t k = (uint32_t)floor(w);
		skysample_bilinear(t, screen_u, screen_v, k, 0, b);
		skysample_bilinear(t, screen_u, screen_v, k + 1, 0, a);
		f = w - k;
	}
	for (int c = 0; c < 3; c++)
		ret_rgb[c] = b[c] + f * (a[c] - b[c]);
	*ret_transmittance = b[3] + f * (a[3] - b[3]);
}

/* The screen position (u right, v up, [0, 1] inside the frustum) of the
 * unit direction dir in a camera (forward, right, up; tan of half the
 * vertical field of view; aspect): sky.glsl's sky_aerial_screen_uv, a
 * direction behind the camera far off screen. */
static inline void skysample_screen_uv(const double fwd[3], const double right[3],
				       const double up[3], double tan_half_vfov, double aspect,
				       const double dir[3], double *ret_u, double *ret_v)
{
	double z = dir[0] * fwd[0] + dir[1] * fwd[1] + dir[2] * fwd[2];
	double x = dir[0] * right[0] + dir[1] * right[1] + dir[2] * right[2];
	double y = dir[0] * up[0] + dir[1] * up[1] + dir[2] * up[2];
	if (!(z > 1e-6))
		z = 1e-6;
	*ret_u = 0.5 + 0.5 * x / (tan_half_vfov * aspect) / z;
	*ret_v = 0.5 + 0.5 * y / tan_half_vfov / z;
}

/* The inverse: the unit direction through screen position (u, v) of the
 * camera, as the aerial pass makes a froxel's ray. */
static inline void skysample_screen_dir(const double fwd[3], const double right[3],
					const double up[3], double tan_half_vfov, double aspect,
					double u, double v, double ret_dir[3])
{
	double x = (2.0 * u - 1.0) * tan_half_vfov * aspect, y = (2.0 * v - 1.0) * tan_half_vfov;
	double d[3], n = 0.0;
	for (int k = 0; k < 3; k++) {
		d[k] = fwd[k] + x * right[k] + y * up[k];
		n += d[k] * d[k];
	}
	n = sqrt(n);
	for (int k = 0; k < 3; k++)
		ret_dir[k] = d[k] / n;
}

/* Aerial perspective from a panorama (struct sky_shm_panorama p, its
 * texels t: RGBA32F, RGB the natural log of the radiance) toward the unit
 * direction dir in the panorama's eye frame (east-north-up), distance_km
 * along it: in-scattered RGB radiance and the mean transmittance. As
 * sky.glsl's sky_aerial_dir reads a panorama: one trilinear lookup of
 * log-RGB and A at skymap_panorama_uv of the direction's azimuth and
 * elevation and at the slice coordinate w (skymap_aerial_slice) clamped to
 * [0, depth - 1], then exp of RGB; for w < 0 (between the eye and slice 0)
 * linear from (0, 0, 0, 1) at the eye (w = -1) to that value. */
static inline void skysample_panorama(const struct skysample_table *t,
				      const struct sky_shm_panorama *p,
				      const struct sky_shm_state *st, const double dir[3],
				      double distance_km, double ret_rgb[3],
				      double *ret_transmittance)
{
	double w = skymap_aerial_slice(distance_km, t->depth, st->aerial_range_km,
				       st->aerial_squared != 0);
	if (!(w == w))
		w = -1.0;
	double u, v, a[4], b[4];
	skymap_panorama_uv(p->azimuth0_rad, p->azimuth_step_rad, p->row0, p->row_step,
			   p->horizon_rad, t->width, t->height, p->full_circle != 0,
			   atan2(dir[0], dir[1]), asin(skymap_clamp(dir[2], -1.0, 1.0)), &u, &v);
	double wc = skymap_clamp(w, 0.0, t->depth - 1.0);
	uint32_t k = (uint32_t)floor(wc);
	uint32_t k1 = k + 1 < t->depth ? k + 1 : k;
	double f = wc - k;
	skysample_bilinear(t, u, v, k, 0, a);
	skysample_bilinear(t, u, v, k1, 0, b);
	double m = w < 0.0 ? (w + 1.0 > 0.0 ? w + 1.0 : 0.0) : 1.0;
	for (int c = 0; c < 3; c++)
		ret_rgb[c] = m * exp(a[c] + f * (b[c] - a[c]));
	*ret_transmittance = 1.0 + m * (a[3] + f * (b[3] - a[3]) - 1.0);
}

/* 1 when a ray from the observer along cos-zenith mu meets the ground. */
static inline int skysample_hits_ground(const struct sky_shm_state *st, double mu)
{
	return mu < skymap_horizon_cos(st->bottom_radius_km, st->altitude_km);
}

/* The transmittance from the observer to a light in direction dir (unit,
 * ENU): 0 when the light is below the geometric horizon. */
static inline void skysample_light_transmittance(const struct skysample_table *t,
						 const struct sky_shm_state *st,
						 const double dir[3], double ret_rgb[3])
{
	if (skysample_hits_ground(st, dir[2])) {
		ret_rgb[0] = ret_rgb[1] = ret_rgb[2] = 0.0;
		return;
	}
	skysample_transmittance(t, st, st->altitude_km, dir[2], ret_rgb);
}

/* The sun's illuminance at the observer on a surface facing the sun (lx per
 * channel): top-of-atmosphere illuminance times transmittance. */
static inline void skysample_sun(const struct skysample_table *trans,
				 const struct sky_shm_state *st, double ret_lx[3])
{
	double tr[3];
	skysample_light_transmittance(trans, st, st->sun_direction, tr);
	for (int c = 0; c < 3; c++)
		ret_lx[c] = st->sun_illuminance_lx[c] * tr[c];
}

/* Quadrature of skysample_ambient: midpoint rule, SKYSAMPLE_AMBIENT_EL rings
 * of elevation over [0, pi/2] and SKYSAMPLE_AMBIENT_AZ sectors of azimuth;
 * the weights cos(theta) sin(theta) dtheta dphi are scaled so that they sum
 * to pi exactly, so a uniform sky of radiance L gives pi L. */
#define SKYSAMPLE_AMBIENT_EL 64
#define SKYSAMPLE_AMBIENT_AZ 128

/* Horizontal sky irradiance (lx per channel): the sky-view radiance
 * integrated over the upper hemisphere, weighted by cos(zenith); no sun. */
static inline void skysample_ambient(const struct skysample_table *t,
				     const struct sky_shm_state *st, double ret_lx[3])
{
	double sum[3] = { 0.0, 0.0, 0.0 }, wsum = 0.0;
	double dth = 0.5 * SKYMAP_PI / SKYSAMPLE_AMBIENT_EL;
	for (int i = 0; i < SKYSAMPLE_AMBIENT_EL; i++) {
		double th = (i + 0.5) * dth;
		double w = cos(th) * sin(th);
		double ring[3] = { 0.0, 0.0, 0.0 };
		for (int j = 0; j < SKYSAMPLE_AMBIENT_AZ; j++) {
			double az = (j + 0.5) * (2.0 * SKYMAP_PI / SKYSAMPLE_AMBIENT_AZ), rgb[3];
			skysample_sky(t, st, 0.5 * SKYMAP_PI - th, az, rgb);
			for (int c = 0; c < 3; c++)
				ring[c] += rgb[c];
		}
		for (int c = 0; c < 3; c++)
			sum[c] += w * ring[c];
		wsum += w * SKYSAMPLE_AMBIENT_AZ;
	}
	for (int c = 0; c < 3; c++)
		ret_lx[c] = SKYMAP_PI * sum[c] / wsum;
}

/* Unit ENU direction of (elevation, azimuth). */
static inline void skysample_direction(double elevation_rad, double azimuth_rad, double ret[3])
{
	ret[0] = cos(elevation_rad) * sin(azimuth_rad);
	ret[1] = cos(elevation_rad) * cos(azimuth_rad);
	ret[2] = sin(elevation_rad);
}

/* Radiance of a light's disk seen along view (unit, ENU), added to ret_rgb:
 * illuminance / (pi r^2) times the transmittance toward the light, inside
 * the angular radius r. limb_u > 0 applies the linear limb-darkening law
 * I(m) = 1 - u (1 - m), normalised by 1 - u/3 so the disk keeps its
 * illuminance. */
static inline void skysample_add_disk(const struct skysample_table *trans,
				      const struct sky_shm_state *st, const double dir[3],
				      const double illuminance_lx[3], double angular_radius_rad,
				      const double view[3], double limb_u, double ret_rgb[3])
{
	if (!(angular_radius_rad > 0.0))
		return;
	double d = view[0] * dir[0] + view[1] * dir[1] + view[2] * dir[2];
	double cr = cos(angular_radius_rad);
	if (d < cr)
		return;
	double tr[3];
	skysample_light_transmittance(trans, st, dir, tr);
	double solid = SKYMAP_PI * angular_radius_rad * angular_radius_rad;
	double limb = 1.0;
	if (limb_u > 0.0) {
		/* sin of the angle from the centre, relative to the radius */
		double s = skymap_safe_sqrt(1.0 - d * d) / sin(angular_radius_rad);
		double m = skymap_safe_sqrt(1.0 - (s > 1.0 ? 1.0 : s * s));
		limb = (1.0 - limb_u * (1.0 - m)) / (1.0 - limb_u / 3.0);
	}
	for (int c = 0; c < 3; c++)
		ret_rgb[c] += illuminance_lx[c] / solid * tr[c] * limb;
}

#endif
