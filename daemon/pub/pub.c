/* pub.c - sealed shared memory with seqlocked slots and a futex generation. */
#include "pub.h"

#include <assert.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <linux/futex.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "aplan.h"
#include "eng.h"
#include "skycloud.h"
#include "skymap.h"

#define ALIGN_UP(x, a) (((x) + (a) - 1) / (a) * (a))
#define SEALS (F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_FUTURE_WRITE | F_SEAL_SEAL)
/* A region the next skyd may write (pub_new_adoptable): no FUTURE_WRITE. */
#define ADOPT_SEALS (F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL)

struct pub {
	int fd;
	int ro_fd;			/* what clients get: read-only open of the same memfd */
	uint8_t *map;
	uint64_t bytes;
	struct sky_shm_header *header;
	uint32_t next_slot;
	/* The next slot while the device writes its tables (pub_claim): its
	 * sequence odd since then; -1 none. */
	int32_t claimed;
	/* The generation pub_publish_ahead also wrote into the next slot,
	 * which pub_publish_staged makes current; 0 none. */
	uint64_t staged;
	struct state_table_quality shape[STATE_N_TABLES];
	enum state_storage storage;
	uint32_t max_views;
	int seals;
	/* The cloud tables' sizes, 0 when the layout has none (no layer
	 * drawn), and where the next publication copies them from. */
	uint32_t cloud_width, shadow_width;
	const void *cloud_src[2];
};

_Static_assert(offsetof(struct sky_shm_cloud_layer, phase_g) == sizeof(struct skycloud_layer),
	       "a published layer starts with struct skycloud_layer");
_Static_assert((int)SKY_TABLE_CLOUD == (int)STATE_CLOUD_COVERAGE && (int)SKY_TABLE_SHADOW == (int)STATE_CLOUD_SHADOW,
	       "the cloud tables' ids are their dirty bits");

_Static_assert(STATE_MAX_VIEWS == SKY_SHM_MAX_VIEWS, "one bound on views");
_Static_assert(STATE_VIEW_NAME_MAX == SKY_SHM_VIEW_NAME_MAX, "one bound on view names");

/* A region holds view volumes only once some view exists: a scene without
 * views pays nothing for them. */
static uint32_t views_capacity(const struct sky_state *s)
{
	return s->n_views ? SKY_SHM_MAX_VIEWS : 0;
}

/* The cloud tables are in a layout only while something casts (a drawn
 * layer or the terrain): a clear sky's region is what it was before
 * clouds. The terrain alone has maps but no coverage: its entry is one
 * texel, never valid. */
static uint32_t cloud_width(const struct sky_state *s)
{
	if (state_clouds_drawn(s))
		return s->quality.cloud_width;
	return eng_shadow_casters(s) ? 1 : 0;
}

static uint32_t shadow_width(const struct sky_state *s)
{
	return eng_shadow_casters(s) ? s->quality.shadow_width : 0;
}

/* A cloud table's directory entry: float32 RGBA, never scaled. */
static uint64_t cloud_entry(struct sky_shm_table *d, uint32_t id, uint32_t width, uint32_t depth,
			    uint64_t offset)
{
	d->id = id;
	d->format = SKY_FORMAT_RGBA32F;
	d->width = d->height = width;
	d->depth = depth;
	d->texel_bytes = 16;
	d->offset = offset;
	d->bytes = (uint64_t)width * width * depth * 16;
	return ALIGN_UP(offset + d->bytes, 64);
}

static uint8_t *slot_base(const struct pub *p, uint32_t i)
{
	return p->map + p->header->header_bytes + (uint64_t)i * p->header->slot_bytes;
}

int pub_same_layout(const struct pub *p, const struct sky_state *s)
{
	for (int t = 0; t < STATE_N_TABLES; t++) {
		const struct state_table_quality *a = &p->shape[t], *b = &s->quality.t[t];
		uint32_t da = t == STATE_AERIAL ? a->depth : 1, db = t == STATE_AERIAL ? b->depth : 1;
		if (a->width != b->width || a->height != b->height || da != db)
			return 0;
	}
	return p->storage == s->quality.storage && p->max_views >= s->n_views &&
	       p->cloud_width == cloud_width(s) && p->shadow_width == shadow_width(s);
}

/* The geometry of a region for the tables of s with room for max_views
 * views; no generation, no slot. */
static void fill_header(struct sky_shm_header *h, const struct sky_state *s, uint32_t max_views)
{
	uint64_t off = ALIGN_UP(sizeof(struct sky_shm_slot), 64);

	h->magic = SKY_SHM_MAGIC;
	h->layout_version = SKY_SHM_LAYOUT_VERSION;
	h->uv_mapping_version = SKYMAP_VERSION;
	h->header_bytes = (uint32_t)ALIGN_UP(sizeof(*h), 4096);
	h->n_slots = PUB_SLOTS;
	h->n_tables = STATE_N_TABLES;
	for (int t = 0; t < STATE_N_TABLES; t++) {
		const struct state_table_quality *q = &s->quality.t[t];
		struct sky_shm_table *d = &h->tables[t];
		d->id = (uint32_t)t;
		d->format = s->quality.storage == STATE_F16 ? SKY_FORMAT_RGBA16F : SKY_FORMAT_RGBA32F;
		d->width = q->width;
		d->height = q->height;
		d->depth = t == STATE_AERIAL ? q->depth : 1;
		d->texel_bytes = (uint32_t)state_texel_bytes(s->quality.storage);
		d->offset = off;
		d->bytes = state_table_bytes(s, (enum state_table)t);
		off = ALIGN_UP(off + d->bytes, 64);
	}
	if (cloud_width(s)) {
		h->n_tables = STATE_N_ALL_TABLES;
		off = cloud_entry(&h->tables[SKY_TABLE_CLOUD], SKY_TABLE_CLOUD, cloud_width(s), 1, off);
		off = cloud_entry(&h->tables[SKY_TABLE_SHADOW], SKY_TABLE_SHADOW, shadow_width(s), 2, off);
	}
	h->max_views = max_views;
	h->view_offset = off;
	/* Room for a volume or a panorama (always float32 RGBA). */
	uint32_t pw, ph;
	aplan_panorama_shape(s, &pw, &ph);
	uint64_t panorama = (uint64_t)pw * ph * s->quality.t[STATE_AERIAL].depth * 16;
	uint64_t volume = h->tables[STATE_AERIAL].bytes;
	h->view_stride = ALIGN_UP(volume > panorama ? volume : panorama, 64);
	off += h->view_stride * h->max_views;
	/* Page-sized slots let a client map one slot alone. */
	h->slot_bytes = ALIGN_UP(off, 4096);
	h->total_bytes = h->header_bytes + h->slot_bytes * h->n_slots;
}

/* Opens the read-only file clients get. Read-only modes also make a
 * root-less reopen of /proc/PID/fd/N read-write fail; without /proc, the
 * fd alone is handed out and the seals alone hold. */
static void open_readonly(struct pub *p)
{
	char self[64];

	snprintf(self, sizeof(self), "/proc/self/fd/%d", p->fd);
	p->ro_fd = open(self, O_RDONLY | O_CLOEXEC);
}

/* pub_new with the given seals: SEALS, or ADOPT_SEALS for a region that
 * outlives this skyd in systemd's fd store. */
static int create(const struct sky_state *s, uint64_t generation, int seals, struct pub **ret)
{
	struct sky_shm_header h = { 0 };
	struct pub *p;
	int r;

	fill_header(&h, s, views_capacity(s));
	if (h.total_bytes > (uint64_t)SIZE_MAX / 2)
		return -EFBIG;
	p = calloc(1, sizeof(*p));
	if (!p)
		return -ENOMEM;
	p->map = MAP_FAILED;
	p->ro_fd = -1;
	p->claimed = -1;
	p->fd = memfd_create("skyd-tables", MFD_CLOEXEC | MFD_ALLOW_SEALING);
	if (p->fd < 0)
		goto fail_errno;
	if (ftruncate(p->fd, (off_t)h.total_bytes) < 0)
		goto fail_errno;
	p->bytes = h.total_bytes;
	p->map = mmap(NULL, p->bytes, PROT_READ | PROT_WRITE, MAP_SHARED, p->fd, 0);
	if (p->map == MAP_FAILED)
		goto fail_errno;
	/* FUTURE_WRITE spares the mapping made above and no other. */
	if (fcntl(p->fd, F_ADD_SEALS, seals) < 0)
		goto fail_errno;
	p->seals = seals;
	(void)fchmod(p->fd, 0444);
	/* Clients get a read-only file: write() and ftruncate() fail on it
	 * before the seals are even asked. */
	open_readonly(p);
	p->header = (struct sky_shm_header *)p->map;
	*p->header = h;
	p->header->generation = (uint32_t)generation;
	for (int t = 0; t < STATE_N_TABLES; t++)
		p->shape[t] = s->quality.t[t];
	p->storage = s->quality.storage;
	p->max_views = h.max_views;
	p->cloud_width = cloud_width(s);
	p->shadow_width = shadow_width(s);
	/* Even an empty slot checks out: seq even means checksum valid. */
	for (uint32_t i = 0; i < PUB_SLOTS; i++) {
		struct sky_shm_slot *slot = (struct sky_shm_slot *)slot_base(p, i);
		slot->checksum = pub_checksum(p->header, slot, (const uint8_t *)slot);
	}
	/* Slot 0 is current (empty) until the first publication. */
	p->next_slot = 1;
	*ret = p;
	return 0;
fail_errno:
	r = -errno;
	pub_free(p);
	return r;
}

int pub_new(const struct sky_state *s, uint64_t generation, struct pub **ret)
{
	return create(s, generation, SEALS, ret);
}

int pub_new_adoptable(const struct sky_state *s, uint64_t generation, struct pub **ret)
{
	return create(s, generation, ADOPT_SEALS, ret);
}

int pub_new_like(const struct pub *like, const struct sky_state *s, uint64_t generation,
		 struct pub **ret)
{
	return create(s, generation, like->seals, ret);
}

int pub_store_fd(const struct pub *p)
{
	return p->seals == ADOPT_SEALS ? p->fd : -EPERM;
}

void pub_free(struct pub *p)
{
	if (!p)
		return;
	if (p->map != MAP_FAILED)
		munmap(p->map, p->bytes);
	if (p->ro_fd >= 0)
		close(p->ro_fd);
	if (p->fd >= 0)
		close(p->fd);
	free(p);
}

int pub_fd(const struct pub *p)
{
	return p->ro_fd >= 0 ? p->ro_fd : p->fd;
}

uint64_t pub_bytes(const struct pub *p)
{
	return p->bytes;
}

void *pub_map(const struct pub *p)
{
	return p->map;
}

const struct sky_shm_header *pub_header(const struct pub *p)
{
	return p->header;
}

const struct sky_shm_slot *pub_current(const struct pub *p, const uint8_t **ret_base)
{
	uint32_t i = atomic_load_explicit((_Atomic uint32_t *)&p->header->current_slot,
					  memory_order_relaxed);
	uint8_t *base = slot_base(p, i);

	if (ret_base)
		*ret_base = base;
	return (const struct sky_shm_slot *)base;
}

void pub_shm_state(const struct sky_state *s, const struct state_lights *lights,
		   struct sky_shm_state *ret)
{
	struct sky_shm_state o = { 0 };
	const double deg = SKYMAP_PI / 180.0;

	/* Time and place only where the clock lit the tables: unknown, not
	 * zero, when the lights were set as angles. */
	o.utc_unix_s = s->lights_utc_s;
	o.latitude_rad = isnan(s->lights_utc_s) ? NAN : s->clock.lat_deg * deg;
	o.longitude_rad = isnan(s->lights_utc_s) ? NAN : s->clock.lon_deg * deg;
	o.altitude_km = s->altitude_km;
	o.bottom_radius_km = s->atmo.bottom_radius_km;
	o.top_radius_km = s->atmo.top_radius_km;
	for (int c = 0; c < 3; c++) {
		o.ground_albedo[c] = s->atmo.ground_albedo[c];
		o.sun_illuminance_lx[c] = s->sun.illuminance_lx * s->sun.color[c];
		o.moon_illuminance_lx[c] = s->moon.illuminance_lx * s->moon.color[c];
	}
	/* The vectors the engine lit the tables with. */
	memcpy(o.sun_direction, lights->sun, sizeof(o.sun_direction));
	memcpy(o.moon_direction, lights->moon, sizeof(o.moon_direction));
	o.sun_angular_radius_rad = s->sun.angular_radius_deg * deg;
	o.moon_angular_radius_rad = s->moon.angular_radius_deg * deg;

	/* The frame the engine computed the aerial volume in, as for views. */
	state_camera_basis(&s->camera, o.camera_forward, o.camera_right, o.camera_up);
	o.camera_vfov_rad = s->camera.vfov_deg * deg;
	o.camera_aspect = s->camera.aspect;
	o.aerial_range_km = s->quality.aerial_range_km;
	o.aerial_squared = s->quality.aerial_spacing == STATE_SQUARED;
	o.exposure_ev100 = s->exposure_ev100;
	*ret = o;
}

uint64_t pub_checksum(const struct sky_shm_header *h, const struct sky_shm_slot *slot,
		      const uint8_t *base)
{
	uint64_t c = sky_shm_checksum_words(SKY_SHM_CHECKSUM_SEED, &slot->state,
					    sizeof(slot->state) / 8);
	c = sky_shm_checksum_words(c, &slot->clouds, sizeof(slot->clouds) / 8);

	for (uint32_t t = 0; t < h->n_tables && t < SKY_SHM_MAX_TABLES; t++)
		if (slot->valid_tables & (1u << t))
			c = sky_shm_checksum_words(c, base + h->tables[t].offset,
						   h->tables[t].bytes / 8);
	if (!slot->n_views || slot->n_views > SKY_SHM_MAX_VIEWS)
		return c;
	c = sky_shm_checksum_words(c, slot->views, slot->n_views * sizeof(slot->views[0]) / 8);
	for (uint32_t i = 0; i < slot->n_views && i < h->max_views; i++) {
		const struct sky_shm_view *v = &slot->views[i];
		if (!(slot->valid_views & (1u << i)))
			continue;
		if (v->form == SKY_VIEW_PANORAMA)
			c = sky_shm_checksum_words(c, base + v->panorama.offset, v->panorama.bytes / 8);
		else
			c = sky_shm_checksum_words(c, base + h->view_offset + i * h->view_stride,
						   h->tables[STATE_AERIAL].bytes / 8);
	}
	return c;
}

static void futex_wake_all(uint32_t *word)
{
	/* Shared (not PRIVATE): the waiters are other processes. */
	syscall(SYS_futex, word, FUTEX_WAKE, INT_MAX, NULL, NULL, 0);
}

/* The slot's view directory and, with aerial perspective valid, each view's
 * volume or panorama: the engine's aerial table holds the volumes of the
 * plan of s (the state's camera's first), panoramas its published
 * panoramas; a panorama goes into the region of the first view that reads
 * it, and every view reading it points there. in_place: the device wrote
 * them there already (pub_claim), aerial and panoramas are not read. */
static void publish_views(const struct sky_shm_header *h, struct sky_shm_slot *slot,
			  uint8_t *base, const struct sky_state *s,
			  const struct state_lights *lights, uint32_t valid,
			  const void *aerial, const void *panoramas, bool in_place)
{
	const double deg = SKYMAP_PI / 180.0;
	uint32_t n = s->n_views < h->max_views ? s->n_views : h->max_views;
	uint64_t bytes = h->tables[STATE_AERIAL].bytes;
	bool computed = (valid & STATE_BIT(STATE_AERIAL)) && (aerial || in_place);
	struct aplan ap;

	memset(slot->views, 0, sizeof(slot->views));
	slot->n_views = n;
	slot->valid_views = 0;
	if (!n)
		return;
	aplan_make_lit(s, lights, true, &ap);
	for (uint32_t i = 0; i < n; i++) {
		const struct state_view *v = &s->views[i];
		struct sky_shm_view *o = &slot->views[i];
		uint8_t *region = base + h->view_offset + i * h->view_stride;
		double f[3], r[3], u[3];
		snprintf(o->name, sizeof(o->name), "%s", v->name);
		o->altitude_km = isnan(v->altitude_km) ? s->altitude_km : v->altitude_km;
		state_camera_basis(&v->camera, f, r, u);
		memcpy(o->camera_forward, f, sizeof(f));
		memcpy(o->camera_right, r, sizeof(r));
		memcpy(o->camera_up, u, sizeof(u));
		o->camera_vfov_rad = v->camera.vfov_deg * deg;
		o->camera_aspect = v->camera.aspect;
		o->form = v->form;
		int32_t vol = ap.volume[i + 1], k = ap.panorama[i + 1];
		if (vol >= 0) {
			if (computed) {
				if (!in_place)
					memcpy(region, (const uint8_t *)aerial + vol * bytes, bytes);
				slot->valid_views |= 1u << i;
			}
			continue;
		}
		aplan_describe(&ap, k, h->view_offset + (uint64_t)ap.pano[k].view * h->view_stride,
			       &o->panorama);
		if (!computed || (!panoramas && !in_place))
			continue;
		if ((uint32_t)ap.pano[k].view == i && !in_place)
			memcpy(region, (const uint8_t *)panoramas + k * o->panorama.bytes, o->panorama.bytes);
		slot->valid_views |= 1u << i;
	}
}

void pub_set_cloud_tables(struct pub *p, const void *coverage, const void *shadow)
{
	p->cloud_src[0] = coverage;
	p->cloud_src[1] = shadow;
}

/* The shadow maps' frames of s as struct sky_shm_clouds gives them: the
 * engine's (u, v, l and texels per km, eng_cloud_frames) as affine rows
 * to texture coordinates and depth. */
static void shadow_rows(const struct sky_state *s, const struct state_lights *lights,
			struct sky_shm_clouds *ret)
{
	float f[2][16];
	double w = s->quality.shadow_width;

	eng_cloud_frames(s, lights, f);
	for (int k = 0; k < 2; k++) {
		/* u (xyz, u_min), v (xyz, v_min), l (xyz, plane), scale */
		double su = f[k][12] / w, sv = f[k][13] / w;
		for (int i = 0; i < 3; i++) {
			ret->shadow_row_u[k][i] = f[k][i] * su;
			ret->shadow_row_v[k][i] = f[k][4 + i] * sv;
			ret->shadow_row_depth[k][i] = -f[k][8 + i];
		}
		ret->shadow_row_u[k][3] = -f[k][3] * su;
		ret->shadow_row_v[k][3] = -f[k][7] * sv;
		ret->shadow_row_depth[k][3] = f[k][11];
	}
}

/* The slot's cloud block of s (struct sky_shm_clouds): the drawn layers,
 * the field's place, the shadow maps' frames (a layer's or the terrain's)
 * and the cloud's transmittance toward each light from the observer. */
static void cloud_block(const struct sky_state *s, const struct state_lights *lights,
			struct sky_shm_clouds *ret)
{
	struct skycloud_layer layers[SKYCLOUD_MAX_LAYERS];
	int n = state_cloud_layers(s, layers);
	float offset[2] = { (float)s->clouds.offset_km[0], (float)s->clouds.offset_km[1] };
	float o[3] = { 0.0f, 0.0f, (float)s->altitude_km }, rb = (float)s->atmo.bottom_radius_km;

	memset(ret, 0, sizeof(*ret));
	ret->sun_transmittance = ret->moon_transmittance = 1.0;
	/* The terrain alone casts too: its maps have frames. */
	if (eng_shadow_casters(s))
		shadow_rows(s, lights, ret);
	if (n == 0)
		return;
	ret->n_layers = (uint32_t)n;
	ret->extent_km = state_cloud_extent_km(s);
	ret->offset_km[0] = s->clouds.offset_km[0];
	ret->offset_km[1] = s->clouds.offset_km[1];
	double at[2];
	state_cloud_table_offset_km(s, at, ret->table_shift_km);
	ret->period_km = SKYCLOUD_PERIOD_KM;
	ret->placed_utc_s = s->clouds.utc_s;
	for (int i = 0; i < n; i++) {
		memcpy(&ret->layers[i], &layers[i], sizeof(layers[i]));
		ret->layers[i].phase_g = skycloud_types[layers[i].type].phase_g;
		ret->layers[i].albedo = skycloud_types[layers[i].type].albedo;
	}
	for (int k = 0; k < 2; k++) {
		const double *l = k == 0 ? lights->sun : lights->moon;
		float d[3] = { (float)l[0], (float)l[1], (float)l[2] };
		double tau = skycloud_optical_depth(layers, n, offset, rb, o, d, 2.0e3f, 256);
		*(k == 0 ? &ret->sun_transmittance : &ret->moon_transmittance) = exp(-tau);
	}
}

/* The slot's cloud block and, where valid and the engine gave them
 * (pub_set_cloud_tables), the cloud tables, copied: the device writes
 * only the four tables into the slot itself. */
static void publish_clouds(struct pub *p, struct sky_shm_slot *slot, uint8_t *base,
			   const struct sky_state *s, const struct state_lights *lights,
			   uint32_t valid)
{
	const struct sky_shm_header *h = p->header;

	cloud_block(s, lights, &slot->clouds);
	if (h->n_tables < STATE_N_ALL_TABLES)
		return;
	for (int k = 0; k < 2; k++) {
		int t = STATE_CLOUD_COVERAGE + k;
		if (!(valid & STATE_BIT(t)) || !p->cloud_src[k])
			continue;
		memcpy(base + h->tables[t].offset, p->cloud_src[k], h->tables[t].bytes);
		slot->valid_tables |= STATE_BIT(t);
	}
	if (slot->valid_tables & STATE_BIT(STATE_CLOUD_SHADOW))
		slot->clouds.shadow_lights = 1u | (s->moon.illuminance_lx > 0.0 ? 2u : 0u);
}

/* Writes one slot under its seqlock: s and the valid tables, as generation,
 * to become current at apply_time_ns (0: now); tables NULL: the device
 * wrote them there (pub_claim). Touches no header word. */
static void write_slot(struct pub *p, uint32_t i, const struct sky_state *s,
		       const struct state_lights *lights, uint32_t valid,
		       const void *const tables[STATE_N_TABLES], const void *panoramas,
		       const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation,
		       int64_t apply_time_ns)
{
	struct state_lights own;
	struct sky_shm_header *h = p->header;
	uint8_t *base = slot_base(p, i);
	struct sky_shm_slot *slot = (struct sky_shm_slot *)base;
	_Atomic uint32_t *seq = (_Atomic uint32_t *)&slot->seq;
	uint32_t odd = atomic_load_explicit(seq, memory_order_relaxed) | 1u;
	bool in_place = !tables;

	if (!lights) {
		state_lights_of(s, &own);
		lights = &own;
	}
	/* Seqlock writer: odd, fence, data, even with release. A claimed slot
	 * is odd already, since before the device wrote its tables. */
	atomic_store_explicit(seq, odd, memory_order_relaxed);
	atomic_thread_fence(memory_order_release);
	if (i == p->next_slot)
		p->staged = 0;
	slot->generation = generation;
	slot->apply_time_ns = apply_time_ns;
	pub_shm_state(s, lights, &slot->state);
	slot->valid_tables = 0;
	for (int t = 0; t < STATE_N_TABLES; t++)
		if ((valid & STATE_BIT(t)) && (in_place || tables[t])) {
			if (!in_place)
				memcpy(base + h->tables[t].offset, tables[t], h->tables[t].bytes);
			slot->valid_tables |= STATE_BIT(t);
			slot->state.rgb_scale_log2[t] = rgb_scale_log2 ? rgb_scale_log2[t] : 0;
		}
	publish_clouds(p, slot, base, s, lights, valid);
	publish_views(h, slot, base, s, lights, valid, in_place ? NULL : tables[STATE_AERIAL], panoramas,
		      in_place);
	slot->checksum = pub_checksum(h, slot, base);
	atomic_store_explicit(seq, odd + 1, memory_order_release);
	if (p->claimed == (int32_t)i)
		p->claimed = -1;
}

/* Where the views' volumes and panoramas of s go in slot i, from the
 * region's first byte (publish_views' places). */
static void view_targets(const struct pub *p, uint64_t slot_offset, const struct sky_state *s,
			 const struct state_lights *lights, struct eng_target *ret)
{
	const struct sky_shm_header *h = p->header;
	uint32_t n = s->n_views < h->max_views ? s->n_views : h->max_views;
	struct aplan ap;

	aplan_make_lit(s, lights, true, &ap);
	for (uint32_t i = 0; i < n; i++) {
		uint64_t region = slot_offset + h->view_offset + i * h->view_stride;
		int32_t vol = ap.volume[i + 1], k = ap.panorama[i + 1];
		if (vol > 0 && vol < ENG_MAX_VOLUMES)
			ret->volume_offset[vol] = region;
		else if (vol < 0 && k >= 0 && k < ENG_MAX_VOLUMES && (uint32_t)ap.pano[k].view == i)
			ret->panorama_offset[k] = region;
	}
}

int pub_claim(struct pub *p, const struct sky_state *s, const struct state_lights *lights,
	      uint32_t tables, struct eng_target *ret)
{
	struct sky_shm_header *h = p->header;
	uint32_t i = p->next_slot;
	uint8_t *base = slot_base(p, i);
	struct state_lights own;

	if (!pub_same_layout(p, s))
		return -EINVAL;
	if (!lights) {
		state_lights_of(s, &own);
		lights = &own;
	}
	if (p->claimed != (int32_t)i) {
		_Atomic uint32_t *seq = (_Atomic uint32_t *)&((struct sky_shm_slot *)base)->seq;
		atomic_store_explicit(seq, atomic_load_explicit(seq, memory_order_relaxed) | 1u,
				      memory_order_relaxed);
		atomic_thread_fence(memory_order_release);
		p->claimed = (int32_t)i;
		p->staged = 0;
	}
	memset(ret, 0, sizeof(*ret));
	ret->base = p->map;
	ret->tables = tables & STATE_ALL_TABLES;
	uint64_t slot_offset = (uint64_t)(base - p->map);
	for (int t = 0; t < STATE_N_TABLES; t++)
		ret->table_offset[t] = slot_offset + h->tables[t].offset;
	for (int v = 0; v < ENG_MAX_VOLUMES; v++)
		ret->volume_offset[v] = ret->panorama_offset[v] = ENG_NOWHERE;
	view_targets(p, slot_offset, s, lights, ret);
	return 0;
}

void pub_publish_claimed(struct pub *p, const struct sky_state *s, const struct state_lights *lights,
			 uint32_t valid, const int32_t rgb_scale_log2[STATE_N_TABLES],
			 uint64_t generation, int64_t apply_time_ns)
{
	assert(p->claimed == (int32_t)p->next_slot);
	pub_publish_at(p, s, lights, valid, NULL, NULL, rgb_scale_log2, generation, apply_time_ns);
}

void pub_publish(struct pub *p, const struct sky_state *s, uint32_t valid,
		 const void *const tables[STATE_N_TABLES], const void *panoramas,
		 const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation)
{
	pub_publish_at(p, s, NULL, valid, tables, panoramas, rgb_scale_log2, generation, 0);
}

/* Makes slot i current as generation and wakes waiters; the ring's next
 * slot follows it. */
static void make_current(struct pub *p, uint32_t i, uint64_t generation)
{
	struct sky_shm_header *h = p->header;

	atomic_store_explicit((_Atomic uint32_t *)&h->current_slot, i, memory_order_release);
	atomic_store_explicit((_Atomic uint32_t *)&h->generation, (uint32_t)generation,
			      memory_order_release);
	futex_wake_all(&h->generation);
	/* The last slot stays spare for apply-time publications. */
	p->next_slot = (i + 1) % (h->n_slots - 1);
	p->staged = 0;
}

void pub_publish_at(struct pub *p, const struct sky_state *s, const struct state_lights *lights,
		    uint32_t valid,
		    const void *const tables[STATE_N_TABLES], const void *panoramas,
		    const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation,
		    int64_t apply_time_ns)
{
	uint32_t i = p->next_slot;

	write_slot(p, i, s, lights, valid, tables, panoramas, rgb_scale_log2, generation,
		   apply_time_ns);
	make_current(p, i, generation);
}

void pub_publish_ahead(struct pub *p, const struct sky_state *s,
		       const struct state_lights *lights, uint32_t valid,
		       const void *const tables[STATE_N_TABLES], const void *panoramas,
		       const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation,
		       int64_t apply_time_ns)
{
	struct sky_shm_header *h = p->header;

	write_slot(p, h->n_slots - 1, s, lights, valid, tables, panoramas, rgb_scale_log2, generation,
		   apply_time_ns);
	/* The next slot too, not current yet: at the apply time the daemon
	 * only switches to it, instead of copying while the clients wake. */
	write_slot(p, p->next_slot, s, lights, valid, tables, panoramas, rgb_scale_log2, generation,
		   apply_time_ns);
	p->staged = generation;
	/* The word keeps its value: waiters wake, find the slot ahead and
	 * sleep again until its apply time. */
	futex_wake_all(&h->generation);
}

int pub_publish_staged(struct pub *p, uint64_t generation)
{
	if (!generation || p->staged != generation)
		return -ESTALE;
	make_current(p, p->next_slot, generation);
	return 0;
}

void pub_supersede(struct pub *p)
{
	struct sky_shm_header *h = p->header;

	atomic_store_explicit((_Atomic uint32_t *)&h->superseded, 1, memory_order_release);
	atomic_fetch_add_explicit((_Atomic uint32_t *)&h->generation, 1, memory_order_release);
	futex_wake_all(&h->generation);
}


/* Rewrites slot i as an empty, stable slot under its seqlock: no
 * generation, no apply time, no table, a valid checksum. A slot left odd
 * by a writer that died stays torn no longer; a spare slot ahead is not
 * handed out any more. */
static void empty_slot(struct pub *p, uint32_t i)
{
	struct sky_shm_slot *slot = (struct sky_shm_slot *)slot_base(p, i);
	_Atomic uint32_t *seq = (_Atomic uint32_t *)&slot->seq;
	/* From odd (a writer died there) to the next odd, from even to odd. */
	uint32_t s0 = atomic_load_explicit(seq, memory_order_relaxed) | 1u;

	atomic_store_explicit(seq, s0, memory_order_relaxed);
	atomic_thread_fence(memory_order_release);
	slot->generation = 0;
	slot->apply_time_ns = 0;
	slot->valid_tables = 0;
	slot->n_views = 0;
	slot->valid_views = 0;
	slot->checksum = pub_checksum(p->header, slot, (const uint8_t *)slot);
	atomic_store_explicit(seq, s0 + 1, memory_order_release);
}

/* Makes the adopted region consistent for this writer: torn slots and the
 * spare slot emptied, the next slot after the current one. Returns the
 * newest generation the region ever showed (a slot's, or the header's
 * word when nothing was published), which the next publication exceeds. */
static uint64_t take_over(struct pub *p)
{
	struct sky_shm_header *h = p->header;
	uint32_t spare = h->n_slots - 1;
	uint32_t cur = atomic_load_explicit((_Atomic uint32_t *)&h->current_slot,
					    memory_order_acquire);
	uint64_t newest = 0;

	for (uint32_t i = 0; i < h->n_slots; i++) {
		struct sky_shm_slot *slot = (struct sky_shm_slot *)slot_base(p, i);
		uint32_t seq = atomic_load_explicit((_Atomic uint32_t *)&slot->seq,
						    memory_order_acquire);
		/* A generation ahead may have been handed out already: count it. */
		if (!(seq & 1u) && slot->generation > newest)
			newest = slot->generation;
		if ((seq & 1u) || i == spare)
			empty_slot(p, i);
	}
	if (cur >= spare) {
		/* Never current in a region this module wrote; slot 0 is. */
		cur = 0;
		atomic_store_explicit((_Atomic uint32_t *)&h->current_slot, 0, memory_order_release);
	}
	p->next_slot = (cur + 1) % spare;
	return newest ? newest : h->generation;
}

/* Marks a region of another layout superseded through a mapping of our
 * own, so that readers of it look for the new one; returns its header's
 * generation word. */
static uint32_t retire(int fd, uint64_t bytes)
{
	struct pub p = { .fd = -1, .ro_fd = -1 };
	uint32_t g;

	p.map = mmap(NULL, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
	if (p.map == MAP_FAILED)
		return 0;
	p.header = (struct sky_shm_header *)p.map;
	g = p.header->generation;
	pub_supersede(&p);
	munmap(p.map, bytes);
	return g;
}

int pub_adopt(int fd, const struct sky_state *s, struct pub **ret, uint64_t *ret_generation)
{
	struct sky_shm_header h, want, seen;
	struct stat st;
	struct pub *p;
	int seals = fcntl(fd, F_GET_SEALS);

	if (seals < 0)
		return -errno;
	/* FUTURE_WRITE forbids the writable mapping; without SHRINK readers
	 * could be made to fault. Nothing else was ever handed over. */
	if (seals != ADOPT_SEALS)
		return -EPERM;
	if (fstat(fd, &st) < 0)
		return -errno;
	if (st.st_size < (off_t)sizeof(h) || pread(fd, &h, sizeof(h), 0) != (ssize_t)sizeof(h))
		return -EPROTO;
	if (h.magic != SKY_SHM_MAGIC || h.layout_version != SKY_SHM_LAYOUT_VERSION ||
	    h.uv_mapping_version != SKYMAP_VERSION || h.n_slots != PUB_SLOTS ||
	    h.total_bytes != (uint64_t)st.st_size)
		return -EPROTO;
	/* The same geometry as a region made for s now, with the adopted
	 * region's room for views (enough for the views of s). */
	memset(&want, 0, sizeof(want));
	fill_header(&want, s, h.max_views);
	seen = h;
	seen.generation = seen.current_slot = seen.superseded = 0;
	if (h.superseded || memcmp(&seen, &want, sizeof(want)) != 0 ||
	    views_capacity(s) > h.max_views) {
		if (!h.superseded)
			*ret_generation = retire(fd, h.total_bytes);
		else
			*ret_generation = h.generation;
		return -ESTALE;
	}
	p = calloc(1, sizeof(*p));
	if (!p)
		return -ENOMEM;
	p->ro_fd = -1;
	p->fd = -1;
	p->claimed = -1;
	p->map = mmap(NULL, h.total_bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
	if (p->map == MAP_FAILED) {
		int r = -errno;
		pub_free(p);
		return r;
	}
	p->fd = fd;
	p->bytes = h.total_bytes;
	p->header = (struct sky_shm_header *)p->map;
	p->seals = seals;
	for (int t = 0; t < STATE_N_TABLES; t++)
		p->shape[t] = s->quality.t[t];
	p->storage = s->quality.storage;
	p->max_views = h.max_views;
	p->cloud_width = cloud_width(s);
	p->shadow_width = shadow_width(s);
	open_readonly(p);
	*ret_generation = take_over(p);
	*ret = p;
	return 0;
}
