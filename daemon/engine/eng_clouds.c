/* eng_clouds.c - the cloud passes' side of the engine: the block the
 * shaders read (struct gpu_clouds: the drawn layers, the field's place,
 * a shadow map's frame per light), the coverage table and the shadow maps
 * on the device, and whether a computation must redo them. A clear sky
 * (no layer drawn) keeps one texel of each and runs neither pass. */
#include "eng_internal.h"
#include "terrain.h"

#include "skycloudmarch.h"
#include "skyterrain.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

_Static_assert(sizeof(struct skycloud_layer) == 72 &&
	       offsetof(struct gpu_clouds, field) == 288 && offsetof(struct gpu_clouds, terrain) == 304 &&
	       offsetof(struct gpu_clouds, frame) == 336 && offsetof(struct gpu_clouds, shift_km) == 464,
	       "struct gpu_clouds is clouds.glsl's CloudBlock in std430");

/* The frame of a light's map: the box of skycloud_shadow_box_of (the one
 * clients compute too) over the region, from the curvature's drop at its
 * corners, -e^2 / R, to top, in the engine's float lanes. */
static void shadow_frame(const double l[3], double e, double top_km, double rb_km, uint32_t width,
			 struct gpu_shadow_frame *ret)
{
	struct skycloud_shadow_box b;

	skycloud_shadow_box_of(l, e, -e * e / rb_km, top_km, &b);
	memset(ret, 0, sizeof(*ret));
	for (int i = 0; i < 3; i++) {
		ret->u[i] = (float)b.u[i];
		ret->v[i] = (float)b.v[i];
		ret->l[i] = (float)l[i];
	}
	ret->U_MIN_KM = (float)-b.u_half_km;
	ret->V_MIN_KM = (float)b.v_lo_km;
	ret->PLANE_KM = (float)b.plane_km;
	ret->U_TEXELS_PER_KM = (float)(width / (2.0 * b.u_half_km));
	ret->V_TEXELS_PER_KM = (float)(width / fmax(b.v_hi_km - b.v_lo_km, 1e-3));
}

/* The share of the finest caster texel (coverage or terrain) by which a
 * map's light may miss the true one at the casters' top: the maps are
 * made for a light on a grid of horizontal slopes (its east and north
 * components over its up one), so that a light that moves less than a
 * cell keeps the maps, whatever moved it and in which order. Rounding each
 * slope by at most half a cell shifts a shadow cast from the top down to
 * the ground by at most SHADOW_LIGHT_SHARE / sqrt(2) of that texel
 * (docs/performance.md, "Clouds"). */
#define SHADOW_LIGHT_SHARE 0.5
/* Below this up component (about 0.6 degrees) a light's slope is too
 * steep for the grid: its maps follow it exactly. */
#define SHADOW_LIGHT_MIN_UP 0.01

/* The light l's direction on the grid of slopes of cell grid (0: l). */
static void grid_light(const double l[3], double grid, double ret[3])
{
	if (!(grid > 0.0) || !(l[2] > SHADOW_LIGHT_MIN_UP)) {
		memcpy(ret, l, 3 * sizeof(double));
		return;
	}
	double sx = round(l[0] / l[2] / grid) * grid, sy = round(l[1] / l[2] / grid) * grid;
	double n = sqrt(sx * sx + sy * sy + 1.0);
	ret[0] = sx / n;
	ret[1] = sy / n;
	ret[2] = 1.0 / n;
}

/* The frames of the lights that light: the sun's and, while it lights,
 * the moon's, each for its light on the grid of slopes whose cell is
 * SHADOW_LIGHT_SHARE of texel_km at top_km. */
static void light_frames(const struct sky_state *s, const struct state_lights *lights, double map_e,
			 double top_km, double texel_km, struct gpu_clouds *ret)
{
	double grid = top_km > 0.0 ? SHADOW_LIGHT_SHARE * texel_km / top_km : 0.0, l[3];

	grid_light(lights->sun, grid, l);
	shadow_frame(l, map_e, top_km, s->atmo.bottom_radius_km, s->quality.shadow_width, &ret->frame[0]);
	if (s->moon.illuminance_lx > 0.0) {
		grid_light(lights->moon, grid, l);
		shadow_frame(l, map_e, top_km, s->atmo.bottom_radius_km, s->quality.shadow_width,
			     &ret->frame[1]);
	}
}

int eng_fill_clouds(const struct sky_state *s, const struct state_lights *lights,
		    struct gpu_clouds *ret)
{
	double e = state_cloud_extent_km(s), top = 0.0, map_e = e, texel_km = INFINITY;

	memset(ret, 0, sizeof(*ret));
	int n = state_cloud_layers(s, ret->layer);
	bool terrain = state_terrain_set(s);
	if (n == 0 && !terrain)
		return 0;
	for (int i = 0; i < n; i++)
		top = fmax(top, ret->layer[i].top_km);
	if (n > 0) {
		double at[2], shift[2];
		state_cloud_table_offset_km(s, at, shift);
		ret->FIELD_OFFSET_EAST_KM = (float)at[0];
		ret->FIELD_OFFSET_NORTH_KM = (float)at[1];
		ret->shift_km[0] = (float)shift[0];
		ret->shift_km[1] = (float)shift[1];
		ret->FIELD_EXTENT_KM = (float)e;
		ret->FIELD_TEXELS_PER_KM = (float)(s->quality.cloud_width / (2.0 * e));
		texel_km = 2.0 * e / s->quality.cloud_width;
	}
	if (terrain) {
		/* The top is white's height: a bound of the highest texel,
		 * which only the upload knows. The maps hold the whole square
		 * and its peaks, whatever the layers' region. */
		ret->TERRAIN_HALF_KM = (float)(0.5 * s->terrain.extent_km);
		ret->TERRAIN_KM_PER_UNIT = (float)(s->terrain.height_m * 1e-3 / SKYTERRAIN_WHITE);
		ret->TERRAIN_TOP_KM = (float)(s->terrain.height_m * 1e-3);
		ret->TERRAIN_WIDTH_TEXELS = s->terrain.width;
		ret->TERRAIN_HEIGHT_TEXELS = s->terrain.height;
		ret->terrain_size[2] = (uint32_t)s->terrain.hash;
		ret->terrain_size[3] = (uint32_t)(s->terrain.hash >> 32);
		top = fmax(top, s->terrain.height_m * 1e-3);
		map_e = n > 0 ? fmax(e, 0.5 * s->terrain.extent_km) : 0.5 * s->terrain.extent_km;
		texel_km = fmin(texel_km, s->terrain.extent_km / fmax(s->terrain.width, s->terrain.height));
	}
	light_frames(s, lights, map_e, top, texel_km, ret);
	return n;
}

bool eng_shadow_casters(const struct sky_state *s)
{
	return state_clouds_drawn(s) > 0 || state_terrain_set(s);
}

uint32_t eng_cloud_mask(struct eng *e, const struct sky_state *s, const struct gpu_clouds *c, int n,
			uint32_t mask)
{
	uint32_t readers = STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL);

	if (!eng_shadow_casters(s))
		return mask & ~(uint32_t)STATE_CLOUD_TABLES;
	/* Sky-view and aerial read the maps: what they were made from must
	 * be this state's, whatever the caller asked. The coverage table
	 * depends on the layers and the tables' place of the field, the maps
	 * on it and the lights' frames too; the shift is the readers'. Tables
	 * made from this state's are kept, whatever the caller asked: a wind
	 * step within the field's cell moves only the readers. */
	bool field = !e->ct.valid || memcmp(c, &e->ct.key, offsetof(struct gpu_clouds, terrain));
	bool frames = field || memcmp(c->terrain, e->ct.key.terrain,
				      offsetof(struct gpu_clouds, shift_km) - offsetof(struct gpu_clouds, terrain));
	if (!field)
		mask &= ~STATE_BIT(STATE_CLOUD_COVERAGE);
	if (!frames)
		mask &= ~STATE_BIT(STATE_CLOUD_SHADOW);
	if ((mask & readers) && frames)
		mask |= STATE_BIT(STATE_CLOUD_SHADOW);
	/* The maps are made from the coverage table, and the key is set with
	 * the maps: a new field's maps need its table, and a new table its
	 * maps. */
	if ((mask & STATE_BIT(STATE_CLOUD_SHADOW)) && field)
		mask |= STATE_BIT(STATE_CLOUD_COVERAGE);
	if (mask & STATE_BIT(STATE_CLOUD_COVERAGE))
		mask |= STATE_BIT(STATE_CLOUD_SHADOW);
	/* The terrain alone casts: the maps, no coverage table. */
	if (n == 0)
		mask &= ~STATE_BIT(STATE_CLOUD_COVERAGE);
	return mask;
}

/* A float32 RGBA buffer of texels texels (at least one) with a texel view,
 * mapped where the host can read it: what the publisher copies. */
static int cloud_buffer_new(struct eng *e, uint64_t texels, struct gpu_buffer *b, VkBufferView *view,
			    char *err, size_t err_size)
{
	int rc = eng_buffer_new(e, texels * 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
					VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
				VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
				VK_MEMORY_PROPERTY_HOST_CACHED_BIT, b, err, err_size);
	if (rc < 0)
		return rc;
	VkBufferViewCreateInfo vi = { .sType = VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO, .buffer = b->buf,
		.format = VK_FORMAT_R32G32B32A32_SFLOAT, .range = texels * 16 };
	VK_TRY(e->vk.vkCreateBufferView(e->dev, &vi, NULL, view));
	memset(b->map, 0, texels * 16);
fail:
	return rc;
}

static void cloud_buffer_free(struct eng *e, struct gpu_buffer *b, VkBufferView *view)
{
	if (*view)
		e->vk.vkDestroyBufferView(e->dev, *view, NULL);
	*view = VK_NULL_HANDLE;
	eng_buffer_free(e, b);
}

static void set_free(struct eng *e, struct cloud_set *c)
{
	cloud_buffer_free(e, &c->cloud, &c->cloud_view);
	cloud_buffer_free(e, &c->shadow, &c->shadow_view);
	c->valid = c->moon_zero = false;
}

/* BINDING_TERRAIN: the field of s, its 16-bit texels packed two a word,
 * uploaded when its hash changes; one zero word without a field. */
static int ensure_terrain(struct eng *e, const struct sky_state *s, bool *rebind, char *err,
			  size_t err_size)
{
	uint64_t hash = state_terrain_set(s) ? s->terrain.hash : 0;
	struct terrain *t = NULL;
	struct skyterrain view = { 0 };
	uint64_t words = 1;
	int rc;

	if (e->terrain.buf && hash == e->terrain_hash)
		return 0;
	if (hash) {
		if ((rc = state_terrain_get(s, &t, &view, err, err_size)) < 0)
			return rc;
		words = ((uint64_t)view.width * view.height + 1) / 2;
	}
	eng_buffer_free(e, &e->terrain);
	e->terrain_hash = 0;
	rc = eng_buffer_new(e, words * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
			    VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT, 0,
			    &e->terrain, err, err_size);
	if (rc == 0) {
		memset(e->terrain.map, 0, words * 4);
		if (t)
			memcpy(e->terrain.map, view.texels, (size_t)view.width * view.height * 2);
		e->terrain_hash = hash;
		*rebind = true;
	}
	if (t)
		terrain_unref(t);
	return rc;
}

/* Sky-view's light kept per step (BINDING_SV_LIGHT): two floats (sun,
 * moon) per step of each column its invocations march (the row's
 * invocations, 8 a workgroup, times sv_az_group columns each), 0 where
 * nothing casts or where that is over SV_LIGHT_MAX_BYTES (3.3 MB at the
 * default quality). */
#define SV_LIGHT_MAX_BYTES (64u << 20)

static uint64_t sv_light_bytes(const struct eng *e, const struct sky_state *s)
{
	const struct state_table_quality *q = &s->quality.t[STATE_SKYVIEW];
	uint64_t group = e->grain.sv_az_group, lanes = (q->width + 8 * group - 1) / (8 * group) * 8;
	uint64_t bytes = lanes * group * q->height * q->steps * 2 * sizeof(float);

	return eng_shadow_casters(s) && bytes <= SV_LIGHT_MAX_BYTES ? bytes : 0;
}

int eng_sv_kept(const struct eng *e, const struct sky_state *s, struct plan *pl,
		const struct spec *key)
{
	uint64_t bytes = sv_light_bytes(e, s);

	if (!key->v[SPEC_SHADOW_W] || !bytes || e->sv_light.bytes != bytes)
		return SV_KEPT_OFF;
	pl->sv_key.spec = *key;
	pl->sv_key.spec.v[SPEC_SV_KEPT] = 0;
	pl->sv_keyed = true;
	/* Maps remade from the same block are the same maps; kept light is
	 * read only where they were not remade all the same. */
	if (e->sv_light_valid && !pl->run[PASS_SHADOW].on &&
	    !memcmp(&pl->sv_key, &e->sv_light_key, sizeof(pl->sv_key)))
		return SV_KEPT_READ;
	/* Kept where the last sky-view had this key too: a light that
	 * stays in its cell for more than one change. A change that moves
	 * the field (the wind), crosses a cell or moves the observer would
	 * pay the writes for nothing; the one after it, in the same cell,
	 * keeps the light for those that follow. */
	return e->sv_last_valid && !memcmp(&pl->sv_key, &e->sv_last, sizeof(pl->sv_key)) ? SV_KEPT_WRITE
											 : SV_KEPT_OFF;
}

int eng_ensure_clouds(struct eng *e, const struct sky_state *s, bool *rebind, char *err,
		      size_t err_size)
{
	bool drawn = state_clouds_drawn(s) > 0;
	uint64_t cw = drawn ? s->quality.cloud_width : 1;
	uint64_t sw = eng_shadow_casters(s) ? s->quality.shadow_width : 1;
	/* The two maps, then each texel's ice optical depth, four a texel
	 * (SPEC_CLOUD_PHASES; kept whatever the layers, so that a new layer's
	 * type does not remake the buffer). */
	uint64_t cloud_texels = cw * cw, shadow_texels = 2 * sw * sw + (2 * sw * sw + 3) / 4;
	e->shadow_map_bytes = 2 * sw * sw * 16;
	int rc = 0;

	if (!e->clouds.buf) {
		rc = eng_buffer_new(e, sizeof(struct gpu_clouds), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
				    VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT, 0,
				    &e->clouds, err, err_size);
		if (rc < 0)
			return rc;
		memset(e->clouds.map, 0, sizeof(struct gpu_clouds));
		*rebind = true;
	}
	if (!e->ct.cloud.buf || e->ct.cloud.bytes != cloud_texels * 16) {
		cloud_buffer_free(e, &e->ct.cloud, &e->ct.cloud_view);
		rc = cloud_buffer_new(e, cloud_texels, &e->ct.cloud, &e->ct.cloud_view, err, err_size);
		e->ct.valid = false;
		*rebind = true;
	}
	if (rc == 0 && (!e->ct.shadow.buf || e->ct.shadow.bytes != shadow_texels * 16)) {
		cloud_buffer_free(e, &e->ct.shadow, &e->ct.shadow_view);
		rc = cloud_buffer_new(e, shadow_texels, &e->ct.shadow, &e->ct.shadow_view, err, err_size);
		e->ct.valid = e->ct.moon_zero = false;
		*rebind = true;
	}
	/* A set made ahead for other sizes is dropped (made again at the
	 * next eng_submit_ahead, in the bound set's sizes). */
	if (!e->ahead_flight && e->ct_ahead.cloud.buf &&
	    (e->ct_ahead.cloud.bytes != cloud_texels * 16 || e->ct_ahead.shadow.bytes != shadow_texels * 16))
		set_free(e, &e->ct_ahead);
	uint64_t sv_bytes = sv_light_bytes(e, s);
	sv_bytes = sv_bytes ? sv_bytes : 16;
	if (rc == 0 && (!e->sv_light.buf || e->sv_light.bytes != sv_bytes)) {
		eng_buffer_free(e, &e->sv_light);
		rc = eng_buffer_new(e, sv_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
				    VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, &e->sv_light, err, err_size);
		e->sv_light_valid = false;
		*rebind = true;
	}
	if (rc == 0)
		rc = ensure_terrain(e, s, rebind, err, err_size);
	return rc;
}

void eng_free_clouds(struct eng *e)
{
	set_free(e, &e->ct);
	set_free(e, &e->ct_ahead);
	eng_buffer_free(e, &e->clouds);
	eng_buffer_free(e, &e->terrain);
	eng_buffer_free(e, &e->sv_light);
	e->terrain_hash = 0;
	e->sv_light_valid = false;
}

const void *eng_cloud_table(const struct eng *e, int t, size_t *ret_bytes)
{
	const struct gpu_buffer *b = t == STATE_CLOUD_COVERAGE ? &e->ct.cloud
				     : t == STATE_CLOUD_SHADOW ? &e->ct.shadow : NULL;

	if (!b || !b->map || !e->ct.valid)
		return NULL;
	/* The terrain alone casts: the coverage buffer is the dummy. */
	if (t == STATE_CLOUD_COVERAGE && !(e->ct.key.FIELD_EXTENT_KM > 0.0f))
		return NULL;
	if (ret_bytes)
		*ret_bytes = (size_t)(b == &e->ct.shadow ? e->shadow_map_bytes : b->bytes);
	return b->map;
}

int eng_cloud_frames(const struct sky_state *s, const struct state_lights *lights,
		     float ret[2][16])
{
	struct gpu_clouds c;
	int n = eng_fill_clouds(s, lights, &c);

	_Static_assert(sizeof(c.frame[0]) == sizeof(ret[0]), "a frame is 16 floats");
	memcpy(ret, c.frame, sizeof(c.frame));
	/* As the readers take them: where the field was when the maps were
	 * made (clouds.glsl, load_clouds). */
	for (int k = 0; k < 2; k++)
		for (int a = 0; a < 3; a++)
			ret[k][4 * a + 3] += ret[k][4 * a] * c.shift_km[0] + ret[k][4 * a + 1] * c.shift_km[1];
	return n;
}

/* Whether set c holds the tables of block b: the same layers, field,
 * terrain and lights' frames (the shift is the readers'). */
static bool set_holds(const struct cloud_set *c, const struct gpu_clouds *b)
{
	return c->valid && !memcmp(b, &c->key, offsetof(struct gpu_clouds, shift_km));
}

static void swap_sets(struct eng *e)
{
	struct cloud_set t = e->ct;

	e->ct = e->ct_ahead;
	e->ct_ahead = t;
	e->clouds_rebind = true;
}

enum eng_clouds_made eng_clouds_made(const struct eng *e, const struct sky_state *s,
				     const struct state_lights *lights)
{
	struct gpu_clouds b;
	struct state_lights own;

	if (!eng_shadow_casters(s))
		return ENG_CLOUDS_BOUND;
	if (!lights) {
		state_lights_of(s, &own);
		lights = &own;
	}
	eng_fill_clouds(s, lights, &b);
	return set_holds(&e->ct, &b) ? ENG_CLOUDS_BOUND : set_holds(&e->ct_ahead, &b) ? ENG_CLOUDS_AHEAD
										: ENG_CLOUDS_NONE;
}

bool eng_take_ahead(struct eng *e, const struct sky_state *s, const struct state_lights *lights)
{
	if (!e->ct_ahead.valid || eng_clouds_made(e, s, lights) != ENG_CLOUDS_AHEAD)
		return false;
	swap_sets(e);
	return true;
}

void eng_end_ahead(struct eng *e)
{
	if (!e->ahead_flight)
		return;
	e->ahead_flight = false;
	swap_sets(e);
}

int eng_submit_ahead(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		     char *err, size_t err_size)
{
	if (!e->ct.valid || eng_clouds_made(e, s, lights) != ENG_CLOUDS_NONE)
		return 1;
	/* The passes write the bound set: the spare one is bound while
	 * they run, the last computation's tables kept aside. */
	swap_sets(e);
	e->ahead_flight = true;
	int rc = eng_submit_to(e, s, lights, STATE_CLOUD_TABLES, NULL, err, err_size);
	if (rc < 0)
		eng_end_ahead(e);
	return rc;
}
