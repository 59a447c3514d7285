/* test_demand.c - skyd computes exactly the tables its clients use: per kind
 * of scene, the set `status` reports as computed is the expected one and the
 * published tables are bit-identical to a full recompute of the same state,
 * whether the device writes them into the slot (publish: direct) or skyd
 * copies them there (publish: copy). */
#include <math.h>
#include <sys/mman.h>
#include <sys/stat.h>

#include "daemon_harness.h"
#include "aplan.h"
#include "eng.h"
#include "skyproto.h"
#include "skysample.h"
#include "state.h"
#include "test.h"

static char reply[1 << 16];
static struct eng *ref_eng;		/* the full recompute, in this process */
static struct sky_state mirror;		/* the daemon's state as the test set it */
static const char *const small[] = { HARNESS_SMALL, NULL };

static void mirror_set(const char *pairs)
{
	char buf[512], err[256], *save = NULL;

	snprintf(buf, sizeof(buf), "%s", pairs);
	for (char *p = strtok_r(buf, " ", &save); p; p = strtok_r(NULL, " ", &save))
		if (state_set_pair(&mirror, p, NULL, err, sizeof(err)) < 0)
			FAIL("mirror %s: %s", p, err);
}

static const char *status_value(struct conn *c, const char *key)
{
	static char buf[256];

	if (conn_request(c, "status", reply, sizeof(reply)) != 0 ||
	    !reply_value(reply, key, buf, sizeof(buf)))
		return "?";
	return buf;
}

/* Sends "set PAIRS", waits for the generation it names, returns it. */
static uint64_t change(struct conn *c, const char *pairs)
{
	char req[600];

	snprintf(req, sizeof(req), "set %s", pairs);
	if (conn_request(c, req, reply, sizeof(reply)) != 0) {
		FAIL("%s: %s", req, reply);
		return 0;
	}
	mirror_set(pairs);
	uint64_t g = reply_u64(reply, "generation");
	CHECK(conn_wait_generation(c, g) == 0);
	return g;
}

/* Waits until status shows generation >= g with nothing in flight. */
static void settle(struct conn *c, uint64_t g)
{
	CHECK(conn_wait_generation(c, g) == 0);
	for (;;) {
		if (conn_request(c, "status", reply, sizeof(reply)) != 0)
			return;
		if (reply_u64(reply, "computing") == 0 && reply_u64(reply, "pending") == 0)
			return;
		/* A computation is in flight: its changed: line ends it. */
		CHECK(conn_wait_generation(c, c->event_generation + 1) == 0);
	}
}

/* The current slot's valid tables are bit-identical to a full recompute of
 * the mirrored state, and its valid set is expect. */
static void check_slot(const uint8_t *map, uint32_t expect, const char *what)
{
	const struct sky_shm_header *h = (const void *)map;
	uint32_t cur = __atomic_load_n(&h->current_slot, __ATOMIC_ACQUIRE);
	const uint8_t *base = map + h->header_bytes + (uint64_t)cur * h->slot_bytes;
	const struct sky_shm_slot *slot = (const void *)base;
	struct eng_timing t;
	char err[256];

	if (slot->valid_tables != expect)
		FAIL("%s: valid tables 0x%x, expected 0x%x", what, slot->valid_tables, expect);
	if (eng_compute(ref_eng, &mirror, STATE_ALL_TABLES, &t, err, sizeof(err)) < 0) {
		FAIL("reference: %s", err);
		return;
	}
	for (int i = 0; i < STATE_N_TABLES; i++) {
		if (!(slot->valid_tables & STATE_BIT(i)))
			continue;
		size_t bytes;
		const void *ref = eng_table(ref_eng, (enum state_table)i, &bytes);
		/* The engine's aerial table holds the views' volumes after the
		 * state's own. */
		if (bytes < h->tables[i].bytes ||
		    memcmp(ref, base + h->tables[i].offset, h->tables[i].bytes))
			FAIL("%s: %s differs from a full recompute", what, state_table_names[i]);
	}
}

/* Closes c with the close verb and waits for the daemon's end of the
 * stream: skyd has dropped the client (and its demand) by then. */
static void hang_up(struct conn *c)
{
	char line[1024];

	CHECK(conn_request(c, "close", reply, sizeof(reply)) == 0);
	while (conn_line(c, line, sizeof(line)) >= 0)
		;
	conn_close(c);
}

#define EXPECT(c, key, value)                                                          \
	do {                                                                           \
		const char *v_ = status_value(c, key);                                 \
		if (strcmp(v_, value))                                                 \
			FAIL("%s: %s is '%s', expected '%s'", __func__, key, v_, value); \
	} while (0)

#define T STATE_BIT(STATE_TRANSMITTANCE)
#define M STATE_BIT(STATE_MULTISCATTER)
#define S STATE_BIT(STATE_SKYVIEW)
#define A STATE_BIT(STATE_AERIAL)

/* Maps the region c received last. */
static const uint8_t *map_last(struct conn *c)
{
	struct stat st;

	if (c->n_fds < 1 || fstat(c->fds[c->n_fds - 1], &st) < 0)
		return NULL;
	const uint8_t *m = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED,
				c->fds[c->n_fds - 1], 0);
	return m == MAP_FAILED ? NULL : m;
}

/* The current slot's view volumes: count, all valid, each bit-identical
 * to the reference engine's volume for the mirrored views. */
static void check_views(const uint8_t *map, uint32_t n, const char *what)
{
	const struct sky_shm_header *h = (const void *)map;
	uint32_t cur = __atomic_load_n(&h->current_slot, __ATOMIC_ACQUIRE);
	const uint8_t *base = map + h->header_bytes + (uint64_t)cur * h->slot_bytes;
	const struct sky_shm_slot *slot = (const void *)base;
	uint64_t bytes = h->tables[STATE_AERIAL].bytes;
	size_t all, pano_all;
	const uint8_t *ref = eng_table(ref_eng, STATE_AERIAL, &all);	/* check_slot computed it */
	const uint8_t *panos = eng_panoramas(ref_eng, &pano_all);
	struct aplan ap;
	aplan_make(&mirror, true, &ap);
	uint64_t one = aplan_panorama_texels(&ap) * 16;

	struct skysample_table none;
	CHECK(skysample_check_layout(h, h->total_bytes) == 0);
	CHECK(skysample_view_from_slot(h, base, "nobody", &none, NULL) == -ENOENT);
	if (slot->n_views != n || slot->valid_views != (1u << n) - 1) {
		FAIL("%s: %u views, valid 0x%x; expected %u", what, slot->n_views, slot->valid_views, n);
		return;
	}
	CHECK(all == bytes * ap.n_volumes && pano_all == aplan_published_bytes(&ap));
	for (uint32_t i = 0; i < n && all == bytes * ap.n_volumes; i++) {
		CHECK(strcmp(slot->views[i].name, mirror.views[i].name) == 0);
		CHECK(slot->views[i].form == mirror.views[i].form);
		if (mirror.views[i].form == SKY_VIEW_PANORAMA) {
			/* Its eye point's panorama, in the region of the first
			 * view that reads it, as the reference marched it. */
			const struct sky_shm_panorama *p = &slot->views[i].panorama;
			int32_t k = ap.panorama[i + 1];
			CHECK(k >= 0 && p->bytes == one && p->width == ap.width && p->height == ap.height &&
			      p->offset == h->view_offset + (uint64_t)ap.pano[k].view * h->view_stride);
			if (k < 0 || !panos || memcmp(base + p->offset, panos + k * one, one))
				FAIL("%s: view %s's panorama differs from a full recompute", what,
				     slot->views[i].name);
			continue;
		}
		/* What libsky's sky_view_aerial_table() finds by name. */
		struct skysample_table t;
		const struct sky_shm_view *sv = NULL;
		CHECK(skysample_view_from_slot(h, base, mirror.views[i].name, &t, &sv) == 0 &&
		      t.texels == base + h->view_offset + i * h->view_stride && sv == &slot->views[i]);
		if (memcmp(base + h->view_offset + i * h->view_stride, ref + ap.volume[i + 1] * bytes, bytes))
			FAIL("%s: view %s differs from a full recompute", what, slot->views[i].name);
	}
}

static void mirror_view(const char *name, double yaw_deg, double pitch_deg)
{
	struct state_view *v = &mirror.views[mirror.n_views++];
	memset(v, 0, sizeof(*v));
	snprintf(v->name, sizeof(v->name), "%s", name);
	v->altitude_km = NAN;
	state_default_camera(&v->camera);
	v->camera.yaw_deg = yaw_deg;
	v->camera.pitch_deg = pitch_deg;
}

/* Display-wall views: each gets its volume (one dispatch), they go with the
 * connection that added them. */
static void test_views(struct conn *ctl, struct daemon *d)
{
	struct conn wall, user;
	char req[256];

	CHECK(conn_open(&user, d->sock) == 0);
	CHECK(conn_request(&user, "subscribe tables=aerial", reply, sizeof(reply)) == 0);
	settle(ctl, ctl->event_generation + 1);
	CHECK(conn_open(&wall, d->sock) == 0);
	CHECK(conn_request(&wall, "view add", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(&wall, "view add name=a/b", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(&wall, "view add name=w yaw=3", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(conn_request(&wall, "view add name=w vfov_deg=200", reply, sizeof(reply)) == SKY_ACK_RANGE);
	CHECK(conn_request(&wall, "view del name=nobody", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(conn_request(&wall, "view turn", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	/* Eight channels of one eye point, 45 degrees apart, as one batch of
	 * requests: each is a change, coalesced while the engine works. */
	uint64_t g = 0;
	for (int i = 0; i < STATE_MAX_VIEWS; i++) {
		char name[16];
		snprintf(name, sizeof(name), "wall%d", i);
		snprintf(req, sizeof(req), "view add name=%s yaw_deg=%d pitch_deg=5", name, 45 * i);
		CHECK(conn_request(&wall, req, reply, sizeof(reply)) == 0);
		g = reply_u64(reply, "generation");
		mirror_view(name, 45 * i, 5);
	}
	CHECK(conn_request(&wall, "view add name=ninth", reply, sizeof(reply)) == SKY_ACK_LIMIT);
	CHECK(conn_request(&user, "view add name=wall0", reply, sizeof(reply)) == SKY_ACK_ARG);
	settle(ctl, g);
	EXPECT(ctl, "last_computed", "aerial");
	EXPECT(ctl, "views", "8");
	CHECK(strstr(reply, "view: name=wall7 index=7 valid=1") != NULL);
	CHECK(conn_request(&wall, "view list", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "view: name=wall3 index=3 altitude_km=observer yaw_deg=135 pitch_deg=5") != NULL);
	/* The first view made a new region with room for the views. */
	CHECK(conn_request(&user, "subscribe tables=aerial", reply, sizeof(reply)) == 0);
	const uint8_t *map = map_last(&user);
	if (!map) {
		FAIL("no region");
		goto out;
	}
	CHECK(((const struct sky_shm_header *)map)->max_views == SKY_SHM_MAX_VIEWS);
	check_slot(map, T | M | S | A, "eight views");	/* sky-view carried */
	check_views(map, 8, "eight views");

	/* A view with the state's camera has the state's volume. */
	CHECK(conn_request(&wall, "view del name=wall7", reply, sizeof(reply)) == 0);
	mirror.n_views--;
	snprintf(req, sizeof(req), "view add name=same yaw_deg=%.17g pitch_deg=%.17g roll_deg=%.17g vfov_deg=%.17g aspect=%.17g",
		 mirror.camera.yaw_deg, mirror.camera.pitch_deg, mirror.camera.roll_deg,
		 mirror.camera.vfov_deg, mirror.camera.aspect);
	CHECK(conn_request(&wall, req, reply, sizeof(reply)) == 0);
	mirror_view("same", 0, 0);
	mirror.views[7].camera = mirror.camera;
	settle(ctl, reply_u64(reply, "generation"));
	check_slot(map, T | M | S | A, "same camera");
	check_views(map, 8, "same camera");
	{
		const struct sky_shm_header *h = (const void *)map;
		const uint8_t *base = map + h->header_bytes + (uint64_t)h->current_slot * h->slot_bytes;
		CHECK(memcmp(base + h->tables[STATE_AERIAL].offset, base + h->view_offset + 7 * h->view_stride,
			     h->tables[STATE_AERIAL].bytes) == 0);
	}

	/* A view elsewhere on the ground: its own eye, its own march. */
	CHECK(conn_request(&wall, "view add name=far east_km=20000", reply, sizeof(reply)) == SKY_ACK_RANGE);
	CHECK(conn_request(&wall, "view del name=same", reply, sizeof(reply)) == 0);
	mirror.n_views--;
	CHECK(conn_request(&wall, "view add name=far east_km=1000 north_km=-20 yaw_deg=90", reply,
			   sizeof(reply)) == 0);
	mirror_view("far", 90, 0);
	mirror.views[7].east_km = 1000;
	mirror.views[7].north_km = -20;
	settle(ctl, reply_u64(reply, "generation"));
	check_slot(map, T | M | S | A, "a view moved");
	check_views(map, 8, "a view moved");
	CHECK(conn_request(&wall, "view list", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "view: name=far index=7 altitude_km=observer yaw_deg=90 pitch_deg=0 roll_deg=0 vfov_deg=60 aspect=1.77777778 east_km=1000 north_km=-20 form=volume mine=1") != NULL);

	/* A time-of-day change recomputes every view, in one dispatch. */
	change(ctl, "sun_elevation_deg=8");
	EXPECT(ctl, "last_computed", "aerial");
	check_slot(map, T | M | A, "views, time of day");
	check_views(map, 8, "views, time of day");

	/* Views of form panorama read their eye point's march: three on the
	 * observer's eye share one panorama, the far view's eye has its own,
	 * and the volumes of the others (and the state's camera) are
	 * resampled from the first. */
	for (int i = 4; i < STATE_MAX_VIEWS; i++) {
		struct state_view *v = &mirror.views[i];
		snprintf(req, sizeof(req), "view add name=%s form=panorama yaw_deg=%.17g pitch_deg=%.17g east_km=%.17g north_km=%.17g",
			 v->name, v->camera.yaw_deg, v->camera.pitch_deg, v->east_km, v->north_km);
		CHECK(conn_request(&wall, req, reply, sizeof(reply)) == 0);
		g = reply_u64(reply, "generation");
		v->form = SKY_VIEW_PANORAMA;
	}
	settle(ctl, g);
	CHECK(conn_request(&wall, "view add name=bad form=sphere", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(&wall, "view list", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "name=wall5 index=5") && strstr(strstr(reply, "name=wall5 index=5"), "form=panorama mine=1"));
	check_slot(map, T | M | A, "panorama views");
	check_views(map, 8, "panorama views");
	{
		const struct sky_shm_header *h = (const void *)map;
		const struct sky_shm_slot *slot =
			(const void *)(map + h->header_bytes + (uint64_t)h->current_slot * h->slot_bytes);
		CHECK(slot->views[5].panorama.offset == slot->views[4].panorama.offset &&
		      slot->views[6].panorama.offset == slot->views[4].panorama.offset &&
		      slot->views[7].panorama.offset != slot->views[4].panorama.offset);
	}

	/* The wall's connection closes: its views are dropped. */
	hang_up(&wall);
	mirror.n_views = 0;
	EXPECT(ctl, "views", "0");
	settle(ctl, ctl->event_generation);
	check_slot(map, T | M | A, "views dropped");
	check_views(map, 0, "views dropped");
out:
	hang_up(&user);
}

/* Computes transmittance alone for s on e; returns whether the column pass
 * ran, -1 on error. */
static int transmittance_on(struct eng *e, const struct sky_state *s)
{
	struct eng_timing t;
	char err[256];

	if (eng_compute(e, s, T, &t, err, sizeof(err)) < 0) {
		FAIL("transmittance: %s", err);
		return -1;
	}
	CHECK(t.computed == T);
	return t.columns;
}

/* Transmittance on e is bit-identical to a fresh engine's for s. */
static void check_fresh(struct eng *e, const struct sky_state *s, const char *what)
{
	struct eng *fresh;
	char err[256];
	size_t a, b;

	if (eng_new(NULL, err, sizeof(err), &fresh) < 0) {
		FAIL("%s: %s", what, err);
		return;
	}
	CHECK(transmittance_on(fresh, s) == 1);	/* a fresh engine has no columns */
	const void *x = eng_table(e, STATE_TRANSMITTANCE, &a), *y = eng_table(fresh, STATE_TRANSMITTANCE, &b);
	if (a != b || memcmp(x, y, a))
		FAIL("%s: transmittance differs from a fresh engine's", what);
	eng_free(fresh);
}

/* Optical depth is linear in the coefficients, so the engine keeps
 * the column densities of the transmittance texels and a change of
 * coefficients alone runs only exp(-sum ext_k L_k); what the columns depend
 * on (a scale height, a layer, the shell, the steps) runs the column pass. */
static void test_columns(void)
{
	struct sky_state s;
	struct eng *e;
	char err[256];

	state_default(&s);
	for (int i = 0; small[i]; i++)
		CHECK(state_set_pair(&s, small[i], NULL, err, sizeof(err)) == 0);
	if (eng_new(NULL, err, sizeof(err), &e) < 0) {
		FAIL("%s", err);
		return;
	}
	CHECK(transmittance_on(e, &s) == 1);
	CHECK(transmittance_on(e, &s) == 0);	/* the same state: kept */
	static const char *const coefficients[] = {
		"mie_scattering_per_km=0.0041", "rayleigh_scattering_per_km=0.006,0.0135,0.033",
		"ozone_absorption_per_km=0.0013,0.0038,0.0002", "mie_absorption_per_km=0.0005",
	};
	for (size_t i = 0; i < sizeof(coefficients) / sizeof(coefficients[0]); i++) {
		CHECK(state_set_pair(&s, coefficients[i], NULL, err, sizeof(err)) == 0);
		if (transmittance_on(e, &s) != 0)
			FAIL("%s ran the column pass", coefficients[i]);
		check_fresh(e, &s, coefficients[i]);
	}
	/* The other tables are unaffected by the columns kept or not. */
	static const char *const geometry[] = {
		"mie_scale_height_km=1.4", "ozone_layer0_width_km=24", "top_radius_km=6470",
		"transmittance_steps=24",
	};
	for (size_t i = 0; i < sizeof(geometry) / sizeof(geometry[0]); i++) {
		if (state_set_pair(&s, geometry[i], NULL, err, sizeof(err)) < 0) {
			FAIL("%s: %s", geometry[i], err);
			continue;
		}
		if (transmittance_on(e, &s) != 1)
			FAIL("%s did not run the column pass", geometry[i]);
		check_fresh(e, &s, geometry[i]);
	}
	/* A constituent switched off changes the set the columns are for. */
	CHECK(state_set_pair(&s, "mie_scattering_per_km=0", NULL, err, sizeof(err)) == 0);
	CHECK(state_set_pair(&s, "mie_absorption_per_km=0", NULL, err, sizeof(err)) == 0);
	CHECK(transmittance_on(e, &s) == 1);
	check_fresh(e, &s, "mie off");
	eng_free(e);
}

/* No subscriber: the start and a change compute nothing. */
static void test_no_subscriber(struct conn *ctl)
{
	EXPECT(ctl, "last_computed", "none");
	EXPECT(ctl, "tables_valid", "none");
	EXPECT(ctl, "computations", "0");
	change(ctl, "sun_elevation_deg=20");
	EXPECT(ctl, "last_computed", "none");
	EXPECT(ctl, "tables_needed", "none");
	EXPECT(ctl, "computations", "0");
}

/* Transmittance only (a view from space): that table alone. map is the
 * region of the subscription to it. */
static void test_transmittance_only(struct conn *ctl, const uint8_t *map)
{
	settle(ctl, ctl->event_generation + 1);
	EXPECT(ctl, "last_computed", "transmittance");
	EXPECT(ctl, "tables_needed", "transmittance");
	check_slot(map, T, "transmittance only");
	/* A weather change on it: transmittance from the kept column densities,
	 * the same bits as a full recompute. */
	uint64_t columns = reply_u64(reply, "column_passes");
	CHECK(columns >= 1);
	change(ctl, "mie_scattering_per_km=0.0041");
	EXPECT(ctl, "last_computed", "transmittance");
	CHECK(reply_u64(reply, "column_passes") == columns);
	check_slot(map, T, "weather, transmittance only");
	change(ctl, "mie_scale_height_km=1.3");
	EXPECT(ctl, "last_computed", "transmittance");
	CHECK(reply_u64(reply, "column_passes") == columns + 1);
	check_slot(map, T, "profile, transmittance only");

	/* A time-of-day change leaves transmittance as it was: carried, not
	 * recomputed. */
	change(ctl, "sun_elevation_deg=12 sun_azimuth_deg=200");
	EXPECT(ctl, "last_computed", "none");
	check_slot(map, T, "time of day, transmittance only");
}

/* sub, the transmittance subscriber, turns to a sky-view dome. */
static void test_skyview(struct conn *ctl, struct conn *sub, const uint8_t *map)
{
	/* A sky-view dome: the missing dependencies and sky-view. */
	CHECK(conn_request(sub, "subscribe tables=skyview", reply, sizeof(reply)) == 0);
	settle(ctl, ctl->event_generation + 1);
	EXPECT(ctl, "last_computed", "multiscatter,skyview");
	EXPECT(ctl, "tables_needed", "transmittance,multiscatter,skyview");
	check_slot(map, T | M | S, "sky-view dome");

	/* Time of day with sky-view in use: sky-view alone. */
	change(ctl, "sun_elevation_deg=5");
	EXPECT(ctl, "last_computed", "skyview");
	check_slot(map, T | M | S, "time of day, sky-view");
	/* Moon and observer position are the same kind of change. */
	change(ctl, "moon_illuminance_lx=0.3 moon_elevation_deg=40");
	EXPECT(ctl, "last_computed", "skyview");
	change(ctl, "altitude_km=1.5");
	EXPECT(ctl, "last_computed", "skyview");
	check_slot(map, T | M | S, "observer position");

	/* A camera change with no aerial perspective in use: nothing. */
	change(ctl, "camera_yaw_deg=90");
	EXPECT(ctl, "last_computed", "none");
	check_slot(map, T | M | S, "camera, no aerial");
}

/* A second client asks for aerial perspective beside the sky-view dome,
 * and leaves. */
static void test_aerial(struct conn *ctl, struct daemon *d, const uint8_t *map)
{
	struct conn sub2;

	/* Aerial perspective added: it alone. */
	CHECK(conn_open(&sub2, d->sock) == 0);
	CHECK(conn_request(&sub2, "subscribe tables=aerial", reply, sizeof(reply)) == 0);
	settle(ctl, ctl->event_generation + 1);
	EXPECT(ctl, "last_computed", "aerial");
	check_slot(map, T | M | S | A, "aerial added");

	/* Camera: aerial only. Time of day: sky-view and aerial. */
	change(ctl, "camera_pitch_deg=10 camera_vfov_deg=40");
	EXPECT(ctl, "last_computed", "aerial");
	check_slot(map, T | M | S | A, "camera");
	change(ctl, "sun_elevation_deg=25");
	EXPECT(ctl, "last_computed", "skyview,aerial");
	check_slot(map, T | M | S | A, "time of day, full scene");

	/* Weather and atmosphere: everything. */
	change(ctl, "mie_scattering_per_km=0.008");
	EXPECT(ctl, "last_computed", "transmittance,multiscatter,skyview,aerial");
	check_slot(map, T | M | S | A, "weather");

	/* A change that leaves every table as it was: no new generation. */
	CHECK(conn_request(ctl, "status", reply, sizeof(reply)) == 0);
	uint64_t gen = reply_u64(reply, "generation"), n = reply_u64(reply, "computations");
	CHECK(conn_request(ctl, "set sun_elevation_deg=25 camera_pitch_deg=10", reply, sizeof(reply)) == 0);
	CHECK(reply_u64(reply, "generation") == gen);
	CHECK(conn_request(ctl, "status", reply, sizeof(reply)) == 0);
	CHECK(reply_u64(reply, "generation") == gen && reply_u64(reply, "computations") == n);

	/* Multi-scattering switched off: sky-view and aerial perspective no
	 * longer need its table, so it is not computed and leaves the slot. */
	change(ctl, "multiscatter_dirs=0");
	EXPECT(ctl, "last_computed", "skyview,aerial");
	EXPECT(ctl, "tables_needed", "transmittance,skyview,aerial");
	check_slot(map, T | S | A, "multi-scattering off");
	change(ctl, "multiscatter_dirs=2");
	EXPECT(ctl, "last_computed", "multiscatter,skyview,aerial");
	check_slot(map, T | M | S | A, "multi-scattering on");

	/* The aerial client leaves: its table is no longer computed. */
	hang_up(&sub2);
	EXPECT(ctl, "demand", "skyview");
	change(ctl, "camera_roll_deg=5 sun_elevation_deg=35");
	EXPECT(ctl, "last_computed", "skyview");
	check_slot(map, T | M | S, "aerial client gone");
}

/* A sample of a table nobody computes: it becomes this connection's
 * demand and the reply comes with the generation that has it. sub stops
 * subscribing first. */
static void test_sampler(struct conn *ctl, struct conn *sub, struct daemon *d, const uint8_t *map)
{
	struct conn sampler;

	CHECK(conn_request(sub, "unsubscribe", reply, sizeof(reply)) == 0);
	change(ctl, "sun_elevation_deg=45");
	EXPECT(ctl, "last_computed", "none");
	CHECK(conn_open(&sampler, d->sock) == 0);
	CHECK(conn_request(&sampler, "sample sky el_deg=20 az_deg=90", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "luminance_cd_m2: ") != NULL);
	EXPECT(ctl, "demand", "skyview");
	EXPECT(ctl, "last_computed", "skyview");
	check_slot(map, T | M | S, "sampled sky-view");
	/* The sampler's demand lasts while it is connected. */
	change(ctl, "sun_elevation_deg=50");
	EXPECT(ctl, "last_computed", "skyview");
	CHECK(conn_request(&sampler, "sample sun", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "illuminance_lx: ") != NULL);
	hang_up(&sampler);
	EXPECT(ctl, "demand", "none");
}

/* The pipelines of the variants in use are cached: a repeat, or a switch
 * back to a variant seen before, builds none; a new one is built off the
 * caller's thread. */
static void test_pipeline_cache(void)
{
	struct eng_timing t;
	char err[256];

	CHECK(eng_compute(ref_eng, &mirror, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	uint64_t built = eng_pipelines_created(ref_eng);
	CHECK(eng_compute(ref_eng, &mirror, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK(eng_pipelines_created(ref_eng) == built);
	/* A black ground is a new variant of the multi-scattering pass (the
	 * term is a specialization constant): one pipeline more, then cached. */
	char albedo[64];
	CHECK(state_get(&mirror, "ground_albedo", albedo, sizeof(albedo)) == 0);
	mirror_set("ground_albedo=0");
	/* It is made on the engine's waiter thread, not in eng_submit: the
	 * daemon's loop goes on answering while lavapipe compiles. */
	CHECK(eng_submit(ref_eng, &mirror, NULL, STATE_ALL_TABLES, err, sizeof(err)) == 0);
	CHECK(eng_pipelines_ordered(ref_eng) == 1);
	CHECK(eng_wait(ref_eng, &t, err, sizeof(err)) == 0);
	CHECK(eng_pipelines_ordered(ref_eng) == 0);
	CHECK(eng_pipelines_created(ref_eng) == built + 1);
	built = eng_pipelines_created(ref_eng);
	char back[96];
	snprintf(back, sizeof(back), "ground_albedo=%s", albedo);
	mirror_set(back);
	CHECK(eng_compute(ref_eng, &mirror, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	mirror_set("ground_albedo=0 multiscatter_dirs=0");
	CHECK(eng_compute(ref_eng, &mirror, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	mirror_set("multiscatter_dirs=2");
	CHECK(eng_submit(ref_eng, &mirror, NULL, STATE_ALL_TABLES, err, sizeof(err)) == 0);
	CHECK(eng_pipelines_ordered(ref_eng) == 0);
	CHECK(eng_wait(ref_eng, &t, err, sizeof(err)) == 0);
	CHECK(eng_pipelines_created(ref_eng) == built);
}

/* One skyd through every scene; publish: "direct" (the device writes the
 * slots) or "copy" (skyd copies the tables in, SKYD_PUBLISH=copy): both
 * publish what the full recompute computes, bit for bit. */
static void serve(const char *publish)
{
	struct daemon d = { 0 };
	struct conn ctl, sub;

	setenv("SKYD_PUBLISH", publish, 1);
	state_default(&mirror);
	for (int i = 0; small[i]; i++)
		mirror_set(small[i]);
	if (daemon_start(&d, small) < 0 || conn_open(&ctl, d.sock) < 0) {
		FAIL("skyd did not start");
		return;
	}
	printf("publish: %s\n", publish);
	/* lavapipe imports host memory (VK_EXT_external_memory_host). */
	if (!strcmp(publish, "copy") || strstr(status_value(&ctl, "device"), "llvmpipe"))
		CHECK(!strcmp(status_value(&ctl, "publish"), publish));
	CHECK(conn_request(&ctl, "subscribe events=1", reply, sizeof(reply)) == 0);
	test_no_subscriber(&ctl);

	CHECK(conn_open(&sub, d.sock) == 0);
	CHECK(conn_request(&sub, "subscribe tables=transmittance", reply, sizeof(reply)) == 0);
	CHECK(sub.n_fds == 1);
	const uint8_t *map = sub.n_fds == 1 ? map_last(&sub) : NULL;
	if (!map) {
		FAIL("no region");
	} else {
		test_transmittance_only(&ctl, map);
		test_skyview(&ctl, &sub, map);
		test_aerial(&ctl, &d, map);
		test_sampler(&ctl, &sub, &d, map);
		test_views(&ctl, &d);
	}
	conn_close(&sub);
	conn_close(&ctl);
	daemon_cleanup(&d);
}

int main(void)
{
	char err[256];

	harness_need_device();
	if (eng_new(NULL, err, sizeof(err), &ref_eng) < 0) {
		printf("skipped: %s\n", err);
		return 77;
	}
	test_columns();
	serve("direct");
	serve("copy");
	test_pipeline_cache();
	eng_free(ref_eng);
	return test_report("test_demand");
}
