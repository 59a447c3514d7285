/* sky.h - libsky, the client library of skyd: the manual and the API.
 *
 * OVERVIEW
 *
 * skyd computes the sky lookup tables of one sky (Hillaire, EGSR 2020) and
 * publishes them in a sealed shared-memory region; it is steered over a
 * Unix socket with a line-based text protocol (proto/PROTOCOL.md). libsky
 * is the C side of both:
 *
 *   - sky_connect() opens the control socket and reads the greeting;
 *     sky_request() sends one request line and waits for its reply;
 *     sky_send() and sky_dispatch() do the same without blocking.
 *   - sky_subscribe() asks for tables; the daemon passes the shared memory
 *     as a file descriptor with the reply and libsky maps it read-only.
 *   - sky_view_begin() / sky_view_end() read the newest published slot in
 *     place (zero copy) and say afterwards whether it stayed intact;
 *     sky_snapshot() copies a slot into the caller's memory, retrying a torn
 *     copy. Neither ever blocks the daemon nor holds anything it waits for.
 *   - sky_wait() sleeps until a new generation is published (a futex on the
 *     header's generation word) or a slot published ahead reaches its apply
 *     time, or, for programs with an event loop,
 *     sky_get_fd() and sky_dispatch() deliver "changed" events.
 *   - sky_sample_*() evaluate the tables on the CPU with the published uv
 *     mappings (proto/skymap.h, proto/skysample.h: the daemon's `sample`
 *     verbs use the same code and agree bit for bit); sky_render() fills an
 *     RGB float image in the equirectangular, perspective or planetarium
 *     fisheye (domemaster) projection.
 *   - sky_gpu_tables() and sky_gpu_state() serve a render client that
 *     samples the tables on its own GPU with the GLSL library installed
 *     beside this header (proto/glsl/sky.glsl; see GPU CLIENTS below and
 *     docs/render-clients.md).
 *
 * A minimal reader:
 *
 *     sky_client *c;
 *     if (sky_connect(NULL, &c) < 0) ...
 *     if (sky_subscribe(c, SKY_TABLES_ALL, 0) < 0) ...
 *     uint32_t gen = 0;
 *     for (;;) {
 *         struct sky_view v;
 *         if (sky_view_begin(c, &v) == 0) {
 *             double rgb[3];
 *             sky_sample_sky(&v, 10.0, 180.0, 0, rgb);
 *             if (sky_view_end(c, &v)) use(rgb);   // else: torn, try again
 *         }
 *         sky_wait(c, v.generation, 1000, &gen);
 *     }
 *     sky_disconnect(c);
 *
 * ERRORS
 *
 * Every function that can fail returns 0 (or a documented non-negative
 * value) on success and a negative errno on failure; sky_strerror() names
 * it. Arguments are checked (-EINVAL). Output parameters (ret_*) are left
 * untouched on failure. libsky never prints, never exits, never aborts,
 * never raises SIGPIPE (it writes with MSG_NOSIGNAL) and installs no
 * signal handlers. A request the daemon refuses is not an error of the call:
 * sky_request() returns the positive ACK code (enum sky_ack in
 * proto/skyproto.h) and the reply holds the message.
 *
 * THREADS
 *
 * A sky_client is not internally locked: calls that take a sky_client must
 * not run concurrently on the same client (use one client per thread, or a
 * lock of your own). Different clients are independent. The sampling and
 * rendering functions take only a const struct sky_view and touch no client
 * state: any number of threads may call them at once on views of the same
 * client, while another thread uses the client, provided the view's memory
 * stays mapped (see LIFETIMES). sky_strerror(), sky_version() and
 * sky_default_path() are thread-safe.
 *
 * EVENT LOOPS
 *
 * sky_get_fd() returns the socket. Poll it for POLLIN (and POLLOUT while
 * sky_want_write() is true); when it is ready, call sky_dispatch() until it
 * returns 0: it reads what is there without blocking, writes what is queued,
 * and returns one event per call (replies to sky_send(), "changed" events,
 * a new shared-memory layout, hang-up). The fd is the same for the life of
 * the connection; sky_reconnect() replaces it (re-register it). The futex
 * wait (sky_wait) is for threads without a loop; both may be used, but not
 * at the same time on the same client.
 *
 * LIFETIMES
 *
 * A view from sky_view_begin() points into the client's mapping: it stays
 * readable until the next call on that client that can replace the mapping
 * (sky_dispatch, sky_request, sky_subscribe, sky_reconnect, sky_disconnect,
 * and sky_wait when the layout changes or, reconnecting by itself, skyd
 * hands out a new region).
 * A view filled by sky_snapshot() points into the caller's buffer and into
 * the mapping's header (read-only fields that never change): the same
 * rule applies to its header pointer only. The memory of the tables is
 * never freed under a view by the daemon: a crash of skyd leaves the
 * mapping readable (with the last tables) until the client replaces it.
 * Strings and replies returned by libsky are owned by libsky; each function
 * says until when they stay valid.
 *
 * FORK
 *
 * Every descriptor libsky opens is close-on-exec. After fork() the child
 * shares the parent's socket: it must not use a sky_client made by the
 * parent except to sky_disconnect() it (which only closes and unmaps, it
 * sends nothing); it connects anew if it needs skyd.
 *
 * RECONNECTING
 *
 * When skyd goes away (crash, restart) the socket reports a hang-up:
 * sky_dispatch() returns SKY_EVENT_HANGUP, sky_request() returns
 * -ECONNRESET (or -EPIPE), sky_wait() keeps timing out. Reconnecting is
 * explicit, with one safe exception: sky_reconnect() connects to the same
 * path again, reads the greeting, renews the subscription (same tables,
 * same flags) and maps the new memory. sky_request() and sky_send() on a
 * client whose hang-up was already seen, or whose write fails because the
 * peer is gone (nothing was delivered), call sky_reconnect() once by
 * themselves and then send. A request that was delivered but whose reply
 * never came is never resent (it may have been applied): the call returns
 * -ECONNRESET and the caller decides.
 *
 * Or libsky reconnects by itself (sky_set_reconnect(), since 0.2): after a
 * hang-up, sky_dispatch() and sky_wait() try again, without ever blocking
 * on a connection, at most once per interval; once the greeting came and
 * the subscription is renewed, sky_dispatch() returns one
 * SKY_EVENT_RECONNECTED, and no SKY_EVENT_HANGUP comes before it. The
 * mapping stays readable all along (LIFETIMES). A skyd restarted by
 * systemd with its file-descriptor store (docs/restart.md) hands back the
 * very memory that is mapped: the mapping, its address and the views into
 * it stay, the generation goes on from where it was, and a reader saw a
 * pause. Any other skyd (restarted by hand, or with another layout) hands
 * out a new region: it is mapped in place of the old one, and the event
 * says so (its userdata is 1).
 *
 * VERSIONS
 *
 * libsky follows semantic versioning (SONAME libsky.so.0). Every function
 * says the version it appeared in. SKY_VERSION is the version of the
 * header; sky_version() that of the library actually loaded. 0.3 reads
 * shared-memory layout 6, whose views may be of form panorama
 * (sky_sample_view_aerial_dir(), the panorama fields of struct
 * sky_gpu_state).
 */
#ifndef SKY_H
#define SKY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "skyproto.h"

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__) && !defined(SKY_NO_VISIBILITY)
#define SKY_EXPORT __attribute__((visibility("default")))
#else
#define SKY_EXPORT
#endif

#define SKY_VERSION_MAJOR 0
#define SKY_VERSION_MINOR 3
#define SKY_VERSION_PATCH 0
#define SKY_MAKE_VERSION(a, b, c) (((a) << 16) | ((b) << 8) | (c))
#define SKY_VERSION SKY_MAKE_VERSION(SKY_VERSION_MAJOR, SKY_VERSION_MINOR, SKY_VERSION_PATCH)

/* The connection to one skyd. Opaque. */
typedef struct sky_client sky_client;
/* One reply to one request: status, message and key: value lines. Opaque. */
typedef struct sky_reply sky_reply;

/* Table bits for sky_subscribe() and struct sky_view (bit = 1 << id of
 * enum sky_shm_table_id). SKY_TABLES_ALL is the sky's four tables; the
 * cloud tables (layout 7: SKY_TABLE_CLOUD, the coverage table, and
 * SKY_TABLE_SHADOW, the shadow maps) are in a region only while something
 * casts, a drawn cloud layer or the terrain (which has maps and no
 * coverage), and come with sky-view or aerial perspective, or by
 * their own bits (SKY_TABLES_CLOUDS). The slot's clouds (struct
 * sky_shm_clouds: the layers, the wind's offset, the maps' frames, the
 * cloud's transmittance toward the lights) are in every slot:
 * v->slot->clouds, n_layers 0 under a clear sky; docs/clouds.md,
 * "Published". */
#define SKY_TABLE_BIT(id) (1u << (id))
#define SKY_TABLES_ALL 0xfu
#define SKY_TABLES_CLOUDS (SKY_TABLE_BIT(SKY_TABLE_CLOUD) | SKY_TABLE_BIT(SKY_TABLE_SHADOW))

/* ---- Library ---------------------------------------------------------- */

/* The version of the loaded library, SKY_MAKE_VERSION(major, minor, patch).
 * Thread-safe. Since 0.1. */
SKY_EXPORT unsigned sky_version(void);

/* A static English description of err (negative errno or positive ACK
 * code: "daemon refused (range)"). Never NULL, never freed. Thread-safe.
 * Since 0.1. */
SKY_EXPORT const char *sky_strerror(int err);

/* Writes the default socket path into buf: $XDG_RUNTIME_DIR/skyd/control
 * when XDG_RUNTIME_DIR is set and that socket exists, else
 * /run/skyd/control (also when neither exists: connecting then fails
 * with -ENOENT and names the path). Returns the length, -ENAMETOOLONG if
 * buf is too small (or the path exceeds sun_path), -EINVAL on bad args.
 * Thread-safe (reads the environment). Since 0.1. */
SKY_EXPORT int sky_default_path(char *buf, size_t size);

/* ---- Connection -------------------------------------------------------- */

/* Connects to skyd at path (NULL: sky_default_path()), blocking, and reads
 * the greeting "OK skyd <version>". On success *ret_client is a new client
 * the caller frees with sky_disconnect(). Errors: -ENOENT / -ECONNREFUSED
 * (no daemon), -EACCES, -ETIMEDOUT (no greeting within the timeout, 5 s),
 * -EPROTO (not skyd), -EPROTONOSUPPORT (another protocol major version),
 * -EAGAIN (skyd is at its max_connections: try again later).
 * Since 0.1. */
SKY_EXPORT int sky_connect(const char *path, sky_client **ret_client);

/* Closes the connection, unmaps the shared memory and frees the client and
 * everything it returned (replies, views into its mapping). NULL is a
 * no-op. Sends nothing, so it is safe in a forked child. Since 0.1. */
SKY_EXPORT void sky_disconnect(sky_client *c);

/* Reconnects to the path given to sky_connect(): drops the old socket (and
 * every queued request and undelivered event), connects, reads the greeting
 * and, if the client had subscribed, subscribes again with the same tables
 * and flags and maps the new memory (the old mapping is released; since
 * 0.2 the memory already mapped, handed back by a skyd that adopted it,
 * stays mapped where it is). 0 or the error of sky_connect() /
 * sky_subscribe(); on failure the client stays disconnected and may try
 * again. Blocks like sky_connect(). Since 0.1. */
SKY_EXPORT int sky_reconnect(sky_client *c);
/* Reconnect by itself after a hang-up (RECONNECTING): interval_ms > 0
 * turns it on, 0 off (the default). While disconnected, sky_dispatch() and
 * sky_wait() make at most one connection attempt per interval_ms, the
 * first at once, and never block on one: a loop that polls sky_get_fd()
 * must call sky_dispatch() at least every interval_ms while it returns
 * -ENOTCONN (a poll timeout does it), and again when the new socket (the
 * fd may change: re-register it) is readable. sky_dispatch() then returns
 * 0 instead of -ENOTCONN, and no SKY_EVENT_HANGUP: one
 * SKY_EVENT_RECONNECTED when the greeting came and the subscription was
 * renewed. sky_wait() then reads the socket too (queueing what comes for
 * sky_dispatch()) and sleeps at most interval_ms at a time, so that a
 * client that only waits comes back as well. 0 or -EINVAL. Since 0.2. */
SKY_EXPORT int sky_set_reconnect(sky_client *c, int interval_ms);

/* The protocol version from the greeting ("1"), owned by the client, valid
 * until sky_reconnect() or sky_disconnect(). Since 0.1. */
SKY_EXPORT const char *sky_protocol_version(const sky_client *c);

/* Timeout of the blocking calls (connect's greeting, sky_request, and
 * sky_subscribe) in milliseconds; < 0: forever. Default 5000. A request
 * that times out closes the connection (its reply could otherwise arrive
 * as the reply of the next request): the next call reconnects. Since 0.1. */
SKY_EXPORT void sky_set_timeout(sky_client *c, int timeout_ms);

/* ---- Requests ---------------------------------------------------------- */

/* Sends one request line (no newline; at most SKY_PROTO_LINE_MAX - 1
 * bytes, no control characters) and waits for its reply. Events and replies
 * to earlier sky_send() requests that arrive first are queued for
 * sky_dispatch(). "batch" and the lines after it up to "end" get no
 * reply from the daemon (PROTOCOL.md): for them sky_request() returns 0 at
 * once with an empty reply, and "end" returns the outcome of the whole
 * batch. Returns 0 when the daemon answered OK, the positive ACK
 * code when it refused (the request changed nothing), or -errno: -EINVAL
 * (bad line), -ETIMEDOUT, -ECONNRESET (the daemon went away after the line
 * was delivered: it may or may not have been applied), -EPROTO (garbled
 * reply). If ret_reply is not NULL it gets the reply (OK or ACK), which the
 * caller frees with sky_reply_free(); on -errno it is untouched. Since 0.1. */
SKY_EXPORT int sky_request(sky_client *c, const char *line, sky_reply **ret_reply);

/* Queues one request line to be written without blocking (part of it may
 * be written at once; the rest by sky_dispatch()). Its reply comes back as
 * a SKY_EVENT_REPLY from sky_dispatch() carrying userdata. At most 64
 * requests may wait for their replies: -EAGAIN beyond. Since 0.1. */
SKY_EXPORT int sky_send(sky_client *c, const char *line, uint64_t userdata);

/* Accessors of a reply. Strings are owned by the reply and valid until
 * sky_reply_free(). Thread-safe on a reply no thread frees. Since 0.1. */
/* 0 for OK, else the ACK code. */
SKY_EXPORT int sky_reply_ack(const sky_reply *r);
/* The ACK message ("{set} sun_elevation_deg: 91 is above 90"), "" for OK. */
SKY_EXPORT const char *sky_reply_message(const sky_reply *r);
/* Number of "key: value" lines before OK / ACK. */
SKY_EXPORT size_t sky_reply_count(const sky_reply *r);
/* Key and value of line i (< count), NULL past the end. */
SKY_EXPORT const char *sky_reply_key(const sky_reply *r, size_t i);
SKY_EXPORT const char *sky_reply_value(const sky_reply *r, size_t i);
/* Value of the first line with that key, NULL if none. */
SKY_EXPORT const char *sky_reply_get(const sky_reply *r, const char *key);
/* Frees a reply; NULL is a no-op. Since 0.1. */
SKY_EXPORT void sky_reply_free(sky_reply *r);

/* ---- Events and loop integration ----------------------------------------- */

enum sky_event_type {
	SKY_EVENT_NONE = 0,
	SKY_EVENT_REPLY = 1,		/* reply to sky_send(): userdata, ack, reply */
	SKY_EVENT_CHANGED = 2,		/* a new generation: generation, tables */
	SKY_EVENT_LAYOUT = 3,		/* a new shared memory was mapped: old views are gone */
	SKY_EVENT_HANGUP = 4,		/* skyd closed the connection; see RECONNECTING */
	SKY_EVENT_FAILED = 5,		/* a recompute failed: generation, message; the
					 * last good tables stay published */
	SKY_EVENT_RECONNECTED = 6,	/* sky_set_reconnect: connected again and the
					 * subscription renewed; generation: the
					 * header's now; tables: those subscribed;
					 * userdata: 1 if a new region was mapped (old
					 * views are gone, as after SKY_EVENT_LAYOUT),
					 * 0 if the same memory stays mapped. Since 0.2 */
};

struct sky_event {
	enum sky_event_type type;
	uint64_t userdata;		/* SKY_EVENT_REPLY: as given to sky_send();
					 * SKY_EVENT_RECONNECTED: 1 new region, 0 same */
	int ack;			/* SKY_EVENT_REPLY: 0 OK, else the ACK code */
	const sky_reply *reply;		/* SKY_EVENT_REPLY: valid until the next sky_dispatch()
					 * or any other call on the client */
	uint32_t generation;		/* SKY_EVENT_CHANGED */
	uint32_t tables;		/* SKY_EVENT_CHANGED: SKY_TABLE_BIT mask that changed */
	const char *message;		/* SKY_EVENT_FAILED: why, valid like reply */
};

/* The socket to poll (POLLIN; POLLOUT while sky_want_write()), -ENOTCONN
 * after a hang-up until sky_reconnect(). Since 0.1. */
SKY_EXPORT int sky_get_fd(const sky_client *c);

/* True while queued request bytes wait for the socket to drain. Since 0.1. */
SKY_EXPORT bool sky_want_write(const sky_client *c);

/* Never blocks. Writes what is queued, reads what the socket holds, and
 * returns 1 with one event in *ret_event, or 0 when nothing is pending (poll
 * again). Call it until it returns 0 after every wake-up. After
 * SKY_EVENT_HANGUP it returns -ENOTCONN until sky_reconnect() (reconnecting
 * by itself, sky_set_reconnect(), it tries again instead and returns 0).
 * -EPROTO on a garbled stream (the connection is then closed). Since 0.1. */
SKY_EXPORT int sky_dispatch(sky_client *c, struct sky_event *ret_event);

/* ---- Shared memory --------------------------------------------------------- */

enum sky_subscribe_flags {
	SKY_SUBSCRIBE_EVENTS = 1,	/* also send "changed" event lines (sky_dispatch) */
};

/* Subscribes to the tables in the mask (SKY_TABLE_BIT of each, the cloud
 * tables' SKY_TABLES_CLOUDS among them since layout 7; the daemon adds
 * what they depend on) and maps the shared memory passed with the
 * reply, read-only. A second call changes the subscription. When the daemon
 * later publishes a new region (new table sizes) it sends it with a
 * "layout:" line: sky_dispatch() maps it and returns SKY_EVENT_LAYOUT;
 * until then the old region stays mapped and readable (the daemon bumps
 * its generation once more when it retires it, so sky_wait() wakes up:
 * call sky_dispatch() then). Returns 0, the
 * positive ACK code, or -errno: -EPROTO (no descriptor came, or the header
 * fails its checks), -EPROTONOSUPPORT (layout or uv-mapping version this
 * library does not know). Blocking, like sky_request(). Since 0.1. */
SKY_EXPORT int sky_subscribe(sky_client *c, uint32_t tables, unsigned flags);

/* The header of the mapping (read-only; generation and current_slot change
 * under you: read them atomically), or NULL before sky_subscribe(). Valid
 * like a view (see LIFETIMES). Since 0.1. */
SKY_EXPORT const struct sky_shm_header *sky_header(const sky_client *c);

/* A consistent view of one slot. Filled by sky_view_begin() (zero copy) or
 * sky_snapshot() (a copy). Read the fields, do not write them. The state
 * (slot->state, skyproto.h) also carries the light sensor's suggested
 * exposure, slot->state.exposure_ev100 (NaN when skyd suggests none). */
struct sky_view {
	const struct sky_shm_header *header;
	const struct sky_shm_slot *slot;	/* state, generation, valid tables */
	uint32_t generation;			/* header generation when taken (a slot
						 * published ahead, or a superseded
						 * region's slot: its own) */
	uint32_t valid_tables;			/* SKY_TABLE_BIT mask */
	uint32_t slot_index;
	uint32_t seq;				/* the even sequence read at the start */
	const void *slot_base;			/* start of the slot's bytes */
};

/* Apply times: with replication (docs/sync.md) skyd writes a sky computed
 * ahead of its apply time (slot->apply_time_ns, CLOCK_REALTIME) into a spare
 * slot at once. sky_view_begin(), sky_snapshot() and sky_wait() hand out the
 * newest slot whose apply time has passed: before that instant a client
 * gets the old sky, from it the new one, whether or not skyd has made it
 * the current slot yet. Such a view's generation is its slot's (low 32
 * bits), the value skyd's header takes when it makes the slot current. */

/* Points ret_view at the newest stable slot in place, without copying.
 * Never blocks: if the writer holds the newest slot it retries a bounded
 * number of times, then returns -EAGAIN. -ENOTCONN before sky_subscribe().
 * Read what you need, then call sky_view_end(): only if it returns true were
 * the values read consistent; otherwise the writer reused the slot while
 * you read (discard the results, begin again). Since 0.1. */
SKY_EXPORT int sky_view_begin(sky_client *c, struct sky_view *ret_view);

/* True if the slot was not rewritten since sky_view_begin(). Does not
 * release anything (there is nothing to release: a view holds no lock).
 * Since 0.1. */
SKY_EXPORT bool sky_view_end(const sky_client *c, const struct sky_view *v);

/* True if the slot's checksum (skyproto.h: FNV-1a over the state and the
 * valid tables) matches its contents. Meant for a snapshot, or for a
 * zero-copy view before sky_view_end(); costs one pass over the slot's
 * bytes. Thread-safe. Since 0.1. */
SKY_EXPORT bool sky_view_verify(const struct sky_view *v);

/* Bytes sky_snapshot() needs: the slot size of the current layout, 0 before
 * sky_subscribe(). Since 0.1. */
SKY_EXPORT size_t sky_snapshot_size(const sky_client *c);

/* Copies the newest stable slot into buf (size >= sky_snapshot_size(),
 * 64-byte alignment recommended, 8 required) and points ret_view at the
 * copy, which stays consistent for as long as the caller keeps buf. A torn
 * copy is detected by the slot's sequence and retried, up to 16 times:
 * then -EAGAIN. -ENOBUFS if size is too small, -ENOTCONN before
 * sky_subscribe(). Cost: one pass over the whole slot (about 200 us of CPU
 * for the default 1.1 MB layout on a small machine), so a client polling
 * every frame should copy only when the generation moved (compare
 * sky_header()->generation, read atomically, with the view's generation):
 * a render client copying every frame at 60 Hz takes that CPU from the
 * daemon's computation on a machine with few cores. Since 0.1. */
SKY_EXPORT int sky_snapshot(sky_client *c, void *buf, size_t size, struct sky_view *ret_view);

/* Waits until the generation a view would get (the header's, or that of a
 * slot published ahead once its apply time has passed) differs from seen,
 * or timeout_ms passes (< 0: forever, 0: just look). The daemon wakes the
 * futex on every publication; a slot ahead of its apply time bounds the
 * sleep by that instant. 0 and *ret_generation (may be NULL) set to that
 * generation; -ETIMEDOUT; -EINTR if a signal interrupted it; -ENOTCONN
 * before sky_subscribe(). It reads the socket only when the region was
 * superseded (a layout change): then it waits there for the new region,
 * maps it (views into the old one end, as with sky_dispatch), returns its
 * generation even if that equals seen (a number read from the superseded
 * header, sky_header(), may hold it: its last wake-up took it; a view of
 * that region holds its slot's own) and queues what else
 * arrives for sky_dispatch(), or, reconnecting by itself
 * (sky_set_reconnect), to hear of a hang-up. Since 0.1. */
SKY_EXPORT int sky_wait(sky_client *c, uint32_t seen, int timeout_ms, uint32_t *ret_generation);

/* ---- Sampling (thread-safe on a view; see THREADS) ------------------------ */

/* Flags of sky_sample_sky() and sky_render(). */
enum sky_sample_flags {
	SKY_SAMPLE_SUN_DISK = 1,	/* add the sun's disk */
	SKY_SAMPLE_MOON_DISK = 2,	/* add the moon's disk */
	SKY_SAMPLE_LIMB_DARKENING = 4,	/* darken the sun's limb (linear law, u = 0.6, flux kept) */
};

/* Transmittance (RGB, [0, 1]) from altitude_km to the top of the atmosphere
 * along the cosine of the zenith angle mu, for rays above the horizon.
 * -ENODATA if the view has no valid transmittance table. Since 0.1. */
SKY_EXPORT int sky_sample_transmittance(const struct sky_view *v, double altitude_km, double mu,
					double ret_rgb[3]);

/* Sky radiance (RGB, cd/m2 per channel) toward elevation_deg above the
 * horizon and azimuth_deg eastward from north, from the sky-view table at
 * the observer of the view's state. With SKY_SAMPLE_SUN_DISK / MOON_DISK a
 * direction inside a disk also gets illuminance / (pi r^2) times the
 * transmittance toward it (r the angular radius); that needs the
 * transmittance table too. -ENODATA if a needed table is not valid.
 * Since 0.1. */
SKY_EXPORT int sky_sample_sky(const struct sky_view *v, double elevation_deg, double azimuth_deg,
			      unsigned flags, double ret_rgb[3]);

/* Aerial perspective at screen position (screen_u right, screen_v up, both
 * in [0, 1]) of the camera in the view's state, distance_km along the view
 * ray: in-scattered radiance (RGB, cd/m2) and the transmittance (NULL to
 * skip). Apply as L = L_surface * T + in-scattered. Since 0.1. */
SKY_EXPORT int sky_sample_aerial(const struct sky_view *v, double screen_u, double screen_v,
				 double distance_km, double ret_rgb[3], double *ret_transmittance);

/* Aerial perspective of the camera view called name (registered with the
 * protocol's `view add`), at screen position (screen_u, screen_v) of the
 * view's camera, sampled as sky_sample_aerial() samples the state's
 * camera. A view of form volume has its own volume in the slot; one of
 * form panorama (since 0.3) reads its eye point's panorama toward the
 * direction through that screen position (sky_sample_view_aerial_dir()).
 * -ENOENT if the slot has no view of that name, -ENODATA if its aerial
 * perspective is not valid in this slot (nobody subscribed to aerial),
 * -EPROTO if the slot's entry for it is malformed. Since 0.2. */
SKY_EXPORT int sky_sample_view_aerial(const struct sky_view *v, const char *name, double screen_u,
				      double screen_v, double distance_km, double ret_rgb[3],
				      double *ret_transmittance);

/* Aerial perspective of the view called name toward the direction dir (in
 * the view's eye frame: east-north-up at its eye, the observer's for a
 * view at east_km = north_km = 0; normalised here, so any non-zero
 * length), distance_km along it: in-scattered radiance (RGB, cd/m2) and
 * the transmittance (NULL to skip). Either form: a volume through the
 * screen position of dir in the view's camera (off screen: the border
 * froxels), a panorama through its column and row (skysample_panorama():
 * trilinear in the logarithm of the radiance). The same numbers as the
 * GLSL library's sky_aerial_dir() (proto/glsl/sky.glsl) to float rounding.
 * name NULL: the state's camera and the aerial table. -EINVAL for a zero
 * or non-finite dir or a negative distance; else errors as
 * sky_sample_view_aerial(). Thread-safe on a view. Since 0.3. */
SKY_EXPORT int sky_sample_view_aerial_dir(const struct sky_view *v, const char *name,
					  const double dir[3], double distance_km, double ret_rgb[3],
					  double *ret_transmittance);

/* The aerial perspective texels of the camera view called name, for upload
 * to a GPU texture: *ret_texels points into the slot (valid as long as the
 * view of the slot is: until sky_view_end() or while the snapshot buffer
 * lives); *ret_bytes (may be NULL) their size. A view of form volume: laid
 * out as the aerial table (same format, sizes and RGB scale:
 * sky_table_scale()). A view of form panorama (since 0.3): its eye point's
 * panorama, RGBA32F, RGB the natural logarithm of the radiance, never
 * scaled, with the sizes and mapping of the slot's views[] entry
 * (struct sky_shm_panorama; sky_gpu_view_table() and sky_gpu_state() give
 * them); views on one eye point get the same texels. The view's camera is
 * in the slot's views[] entry of the same name (proto/skyproto.h).
 * Errors as sky_sample_view_aerial().
 * Since 0.2. */
SKY_EXPORT int sky_view_aerial_table(const struct sky_view *v, const char *name,
				     const void **ret_texels, size_t *ret_bytes);

/* The factor that turns a table's stored RGB into its values, for a client
 * that reads the texels itself (a GPU upload of the slot's tables or of
 * sky_view_aerial_table()'s): for a float16 table (SKY_FORMAT_RGBA16F)
 * 2^rgb_scale_log2[table_id] of the slot's state, a power of two that skyd
 * picks per table and per slot so that the sky neither overflows nor
 * loses its precision (PROTOCOL.md, "Table storage"); 1 for float32. A is
 * never scaled; the views' volumes share the aerial table's factor. The
 * sampling functions apply it themselves. -EINVAL on bad arguments,
 * -ENODATA if the table is not valid in the view. Since 0.2. */
SKY_EXPORT int sky_table_scale(const struct sky_view *v, uint32_t table_id, double *ret_scale);

/* The sun's transmitted illuminance at the observer (lx per channel, on a
 * surface facing the sun; 0 below the horizon). The same number as the
 * daemon's `sample sun`. Since 0.1. */
SKY_EXPORT int sky_sample_sun(const struct sky_view *v, double ret_lx[3]);

/* Horizontal sky irradiance (lx per channel, no sun): the sky-view table
 * integrated over the upper hemisphere. The same number as `sample
 * ambient`. About 8000 bilinear samples. Since 0.1. */
SKY_EXPORT int sky_sample_ambient(const struct sky_view *v, double ret_lx[3]);

/* ---- Clouds (thread-safe on a view) ------------------------------------- */

/* How sky_sample_clouds() marches; the layers, the coverage table and the
 * shadow maps are the view's own (its slot's struct sky_shm_clouds and
 * tables). NULL params: every default. */
struct sky_cloud_params {
	int steps;			/* of the view march; 0: SKYCLOUD_MARCH_STEPS_MEDIUM */
	int light_steps;		/* 0: each light's published shadow map (a march of 8
					 * steps toward a light without one); > 0: march */
	double jitter;			/* [0, 1): where in its step a sample lies; NULL params: 0.5 */
	double ambient_lx[3];		/* sky irradiance scattered as skylight (E / pi), e.g.
					 * sky_sample_ambient() once per view; 0: none */
};

/* Flag of sky_sample_clouds(): composite the clouds with what is behind
 * them (the sky and the disks of the other flags) and the air in front. */
#define SKY_SAMPLE_CLOUD_COMPOSITE 8

/* The clouds seen from the observer of the view's state toward
 * elevation_deg above the horizon and azimuth_deg eastward from north, up
 * to distance_km (the scene's depth: a surface there, or INFINITY): the
 * slot's cloud layers (none: no cloud, transmittance 1), with the
 * coverage table where the view holds it (else the field's own
 * coverage), lit by the state's sun through the view's transmittance and
 * multi-scattering tables, and by its moon where it lights, each through
 * its published shadow map where valid (else marched toward, light_steps):
 * skycloud_march() of skycloudmarch.h on skycloud_scene_from_slot, the same numbers as the GLSL
 * library's skycloud_march() (proto/glsl/skycloud_march.glsl) to float
 * rounding. Without SKY_SAMPLE_CLOUD_COMPOSITE, ret_rgb is the clouds'
 * own in-scattered radiance (cd/m2); with it, the pixel: the sky behind
 * (sky_sample_sky() with the disk flags; a finite distance_km has no sky
 * behind: black, the caller composites its surface with skycloud_composite)
 * seen through the clouds, with the aerial perspective of the state's
 * camera at the clouds' depth (skycloud_composite). ret_transmittance and
 * ret_depth_km (each may be NULL): the clouds' transmittance along the ray
 * and their mean depth (distance_km where there are none). -EINVAL on bad
 * arguments, -ENODATA if a needed table is not valid in the view. Costs
 * steps times the layers' density (docs/clouds.md, "Drawing clouds in a
 * client"). Since 0.4; the view's own layers and maps with layout 7. */
SKY_EXPORT int sky_sample_clouds(const struct sky_view *v, const struct sky_cloud_params *p,
				 double elevation_deg, double azimuth_deg, double distance_km, unsigned flags,
				 double ret_rgb[3], double *ret_transmittance, double *ret_depth_km);

/* ---- GPU clients ---------------------------------------------------------
 *
 * GPU CLIENTS
 *
 * A render client that samples the tables on its own GPU uploads each table
 * to an image and evaluates it in its shaders with the GLSL library
 * installed beside this header (include/sky/glsl: sky.glsl and the uv
 * mappings skymap.glsl; docs/render-clients.md). Per frame:
 *
 *     struct sky_view v;
 *     struct sky_gpu_table t[SKY_SHM_MAX_TABLES];
 *     struct sky_gpu_state st;
 *     if (sky_view_begin(c, &v) == 0 && v.generation != shown) {
 *         sky_gpu_tables(c, &v, t);          // which tables changed since
 *         sky_gpu_state(&v, NULL, &st);      // the uniforms of this slot
 *         for each present t[i] with t[i].changed_generation != uploaded[i]:
 *             memcpy t[i].texels (t[i].bytes) into a staging buffer
 *         copy st into the staging buffer too
 *         if (sky_view_end(c, &v)) {         // intact: record the copy
 *             submit the staging -> image copies into the back set of images
 *             uploaded[i] = t[i].changed_generation, shown = v.generation
 *         }                                  // else torn: drop the copy, begin again
 *     }
 *
 * Keeping the previous tables until the new upload is done: skyd reuses a
 * slot a couple of publications later, so never let the GPU read the
 * mapping itself while frames render from it. Copy the texels out
 * under sky_view_begin() / sky_view_end() (above), or take a sky_snapshot()
 * and copy from it at leisure, into host memory the client owns; keep two
 * sets of images (and uniforms): frames sample the front set while the copy
 * into the back set runs, and the client swaps them when the copy's fence
 * (or timeline semaphore) has signalled, never before. Every table of a set
 * and its struct sky_gpu_state must come from the same generation (the
 * scale of a float16 table changes from slot to slot): a set whose tables
 * did not all change is completed by copying the unchanged images from the
 * front set on the GPU, or by keeping one image per table per set and
 * uploading to the back set every table whose changed_generation differs
 * from what that set holds.
 *
 * Importing instead of copying (VK_EXT_external_memory_host): the mapping is
 * read-only and page-aligned, each table at map_offset from its start (a
 * multiple of 64 bytes). A driver that accepts read-only host memory can
 * import the pages that hold a table (round map_offset down and the end up
 * to minImportedHostPointerAlignment) as a transfer source and copy from
 * it into an image on the GPU, which saves the CPU copy; the copy must then
 * complete, and sky_view_end() be called after its fence, before the
 * result is trusted (a torn copy is dropped like a torn CPU copy). Images
 * never alias the mapping.
 *
 * Views' aerial perspective (`view add`): upload sky_gpu_view_table()'s
 * texels in place of the aerial table and fill the uniforms with
 * sky_gpu_state(v, name, ...). A view of form panorama (a display wall's
 * channels share their eye point's) is a 3-D image of its own size and
 * format RGBA32F whatever the tables' storage; sample it by direction with
 * sky_aerial_dir() / sky_apply_aerial_dir(), which read a volume as well,
 * never with the screen-position functions.
 */

/* Texel formats of sky_gpu_table.vk_format: the VkFormat enumerants (stable
 * across Vulkan versions) of the two table formats, so that libsky needs no
 * Vulkan header. OpenGL's internal formats are GL_RGBA32F and GL_RGBA16F. */
#define SKY_VK_FORMAT_R32G32B32A32_SFLOAT 109u	/* SKY_FORMAT_RGBA32F */
#define SKY_VK_FORMAT_R16G16B16A16_SFLOAT 97u	/* SKY_FORMAT_RGBA16F */

/* One table of a slot as a GPU client uploads it. Rows are tightly packed
 * (row_pitch_bytes = width * texel_bytes), row 0 first, slices after each
 * other; the texels' RGB times 2^rgb_scale_log2 is the value (float16
 * tables; 0 for float32): pass 2^rgb_scale_log2 to the shaders
 * (sky_gpu_state()'s rgb_scale does), never rescale the texels. */
struct sky_gpu_table {
	uint32_t id;			/* enum sky_shm_table_id, the index in the array */
	uint32_t present;		/* 1: valid in this view; 0: the fields below are 0 */
	uint32_t format;		/* enum sky_shm_format */
	uint32_t vk_format;		/* SKY_VK_FORMAT_* */
	uint32_t width, height, depth;	/* texels; depth 1 for 2-D tables */
	uint32_t texel_bytes;		/* 16 (RGBA32F) or 8 (RGBA16F) */
	uint64_t row_pitch_bytes;	/* width * texel_bytes */
	uint64_t slice_pitch_bytes;	/* row_pitch_bytes * height */
	uint64_t bytes;			/* slice_pitch_bytes * depth */
	const void *texels;		/* the first texel, in the view's memory */
	uint64_t map_offset;		/* texels' offset from the start of the mapping
					 * (zero-copy views; 0 for a snapshot's) */
	int32_t rgb_scale_log2;		/* the slot state's rgb_scale_log2[id] */
	uint32_t changed_generation;	/* the generation from which this table holds
					 * what it holds now: upload when it differs
					 * from the one your image was filled at */
};

/* Describes every table of the view for upload: ret_tables[id] for each id
 * in [0, SKY_SHM_MAX_TABLES), with present = 0 for a table the view does not
 * hold. texels point into the view's memory: valid as the view is (see
 * LIFETIMES), and for a zero-copy view the bytes are only trustworthy once
 * sky_view_end() has returned true after you copied them.
 *
 * changed_generation: skyd republishes a table it did not recompute with the
 * same bytes, so libsky tells a change by the table's contents (format,
 * size, scale and a 64-bit FNV-1a of its bytes, skyproto.h's checksum
 * function): the first generation in which this client saw the present
 * contents, in the generations of its views. Comparing it with the one an
 * image was uploaded at tells whether to upload again. The contents are
 * hashed once per table per new generation (a pass over the tables'
 * bytes: 0.15 ms of CPU for the default 1.1 MB layout on a small machine,
 * docs/render-clients.md); further calls in the same generation cost
 * nothing. A new mapping (layout change, reconnection)
 * starts afresh: every table counts as changed.
 *
 * Returns the SKY_TABLE_BIT mask of the present tables whose
 * changed_generation is the view's generation (>= 0), -EINVAL, or -EAGAIN
 * when the slot of a zero-copy view was rewritten while it was hashed
 * (nothing is recorded: begin a new view). Takes the client (it keeps what
 * it has seen): not thread-safe on one client, like every call that takes
 * one (see THREADS). The cloud tables (ids 4 and 5, layout 7) are listed
 * like the others where the slot holds them: RGBA32F, never scaled, the
 * shadow table of depth 2 (the sun's map, the moon's). Since 0.2; the
 * cloud tables with layout 7. */
SKY_EXPORT int sky_gpu_tables(sky_client *c, const struct sky_view *v,
			      struct sky_gpu_table ret_tables[SKY_SHM_MAX_TABLES]);

/* The aerial perspective of the view called name (`view add`; see
 * sky_view_aerial_table()) described as sky_gpu_tables() describes a table,
 * id SKY_TABLE_AERIAL, with its own changed_generation: a view's volume
 * changes when its camera or the sky does. A view of form volume: the
 * aerial table's format, sizes and scale, a 3-D image like the aerial
 * table's. A view of form panorama (since 0.3): its panorama, format
 * SKY_FORMAT_RGBA32F (vk_format SKY_VK_FORMAT_R32G32B32A32_SFLOAT),
 * texel_bytes 16, rgb_scale_log2 0, width, height and depth the
 * panorama's (columns, rows, slices): a 3-D image sampled by the GLSL
 * library's sky_aerial_dir() with sky_gpu_state()'s panorama fields, with
 * the same linear CLAMP_TO_EDGE sampler as a volume; views that share a
 * panorama share its hash too (one pass over its bytes per generation,
 * whatever the number of views). Returns 1 if it
 * changed in the view's generation, 0 if not, -ENOENT if the slot has no
 * such view, -ENODATA if it is not valid there, -EPROTO if its entry is
 * malformed, -EAGAIN if a zero-copy view was torn, -EINVAL. Keeps what it
 * has seen per name, for up to SKY_SHM_MAX_VIEWS names. Not thread-safe
 * on one client. Since 0.2. */
SKY_EXPORT int sky_gpu_view_table(sky_client *c, const struct sky_view *v, const char *name,
				  struct sky_gpu_table *ret_table);

/* The per-generation uniforms of the GLSL library (proto/glsl/sky.glsl,
 * struct SkyState): vec4s only, so the same bytes are its std140 and its
 * std430 layout. Filled from the slot's struct sky_shm_state by
 * sky_gpu_state(); directions in the observer's east-north-up frame. */
struct sky_gpu_state {
	float sun[4];			/* xyz sun_direction, w sun_angular_radius_rad */
	float sun_illuminance_lx[4];	/* rgb at the top of the atmosphere, w 0 */
	float moon[4];			/* xyz moon_direction, w moon_angular_radius_rad */
	float moon_illuminance_lx[4];	/* rgb, 0 when the moon lights nothing; w 0 */
	float planet[4];		/* bottom_radius_km, top_radius_km, altitude_km, 0 */
	float horizon[4];		/* the geometric horizon at the observer: cos-zenith
					 * (skymap_horizon_cos), sin-zenith, zenith angle
					 * (rad), 0; in double, then rounded */
	float rgb_scale[4];		/* by table id: 2^rgb_scale_log2[id] (1 for float32) */
	float aerial[4];		/* aerial_range_km, aerial_squared (1 or 0),
					 * tan(vfov / 2) and aspect of the volume's camera */
	float camera_forward[4];	/* the aerial volume's camera: xyz, w 0 */
	float camera_right[4];		/* xyz, w 0 */
	float camera_up[4];		/* xyz, w the camera's altitude_km */
	/* A view of form panorama (struct sky_shm_panorama): azimuth0_rad,
	 * azimuth_step_rad, row0, row_step; 0 for a volume. Since 0.3. */
	float panorama[4];
	/* horizon_rad, width, height, and the aerial texture's form: 0 a
	 * volume, 1 a panorama of an arc, 2 of the full circle. Since 0.3. */
	float panorama_grid[4];
};

/* Fills ret_state from the view's slot for the GLSL library. view_name NULL:
 * the aerial volume is the state's camera's (the aerial table); else the
 * camera of the view of that name (`view add`, sky_view_aerial_table()),
 * -ENOENT if the slot has none. The camera_* fields are always the
 * camera's; panorama and panorama_grid (since 0.3) describe a view of
 * form panorama (panorama_grid[3] 1 for an arc of azimuths, 2 for the full
 * circle) and are 0 for a volume, so that sky_aerial_dir() reads either.
 * Thread-safe on a view. Since 0.2. */
SKY_EXPORT int sky_gpu_state(const struct sky_view *v, const char *view_name,
			     struct sky_gpu_state *ret_state);

/* ---- Rendering --------------------------------------------------------- */

enum sky_projection {
	/* Columns: azimuth 0 (north) at the left edge, increasing eastward over
	 * 360 degrees; rows: elevation +90 at the top edge to -90 at the
	 * bottom. Pixel (x, y) is the direction of its centre. */
	SKY_PROJECTION_EQUIRECT = 0,
	/* A pinhole camera looking at (yaw_deg, pitch_deg), roll_deg about
	 * the axis, vfov_deg the vertical field of view, square pixels. */
	SKY_PROJECTION_PERSPECTIVE = 1,
	/* Planetarium domemaster: azimuthal equidistant, 180 degrees, zenith
	 * at the centre, the horizon on the inscribed circle of the
	 * min(width, height) square; the front (azimuth yaw_deg) at the
	 * bottom, azimuth + 90 at the right (as seen from inside the dome).
	 * Pixels outside the circle are black. */
	SKY_PROJECTION_FISHEYE = 2,
};

struct sky_render_params {
	enum sky_projection projection;
	uint32_t width, height;		/* pixels, each >= 1 */
	double yaw_deg;			/* perspective: view azimuth; fisheye: front azimuth */
	double pitch_deg;		/* perspective only */
	double roll_deg;		/* perspective only */
	double vfov_deg;		/* perspective only, (0, 180) */
	unsigned flags;			/* enum sky_sample_flags */
};

/* The unit ENU direction through the centre of pixel (x, y) (x right, y
 * down, the top-left pixel's centre at (0.5, 0.5): pass x + 0.5 for pixel
 * x). Returns 1 and sets ret_dir when the point shows the sky, 0 when it
 * lies outside the fisheye circle, -EINVAL on bad parameters. Since 0.1. */
SKY_EXPORT int sky_render_direction(const struct sky_render_params *p, double x, double y,
				    double ret_dir[3]);

/* The inverse: where direction dir (unit, ENU) lands, in the same continuous
 * pixel coordinates. 1 and ret_x/ret_y when it is in front of the camera
 * (perspective) or above the horizon (fisheye) or anywhere (equirect), 0
 * otherwise. Since 0.1. */
SKY_EXPORT int sky_render_position(const struct sky_render_params *p, const double dir[3],
				   double *ret_x, double *ret_y);

/* Renders the sky of the view into ret_rgb: width * height * 3 floats,
 * linear RGB radiance (cd/m2), rows top to bottom. Below the geometric
 * horizon the sky-view table's value (the ground as the sky-view table
 * holds it). Uses the sky-view table, and the transmittance table for the
 * disks. -ENODATA if they are not valid. Thread-safe. Since 0.1. */
SKY_EXPORT int sky_render(const struct sky_view *v, const struct sky_render_params *p,
			  float *ret_rgb);

#ifdef __cplusplus
}
#endif

#endif
