/* stab.h - the stiff and extreme atmospheres of docs/physics.md as named cases,
 * a seeded random sweep, and the invariants every table must keep.
 *
 * Shared by the numerical tests (which assert) and `skybench stability`
 * (which writes docs/stability.md). Tables are handled as RGBA doubles in
 * the layout of model.h, whether they come from the double-precision model
 * or from the Vulkan engine (float32 or float16, widened).
 */
#ifndef SKYD_STAB_H
#define SKYD_STAB_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "model.h"
#include "state.h"

struct eng;

/* One named case: fill() starts from state_default(). */
struct stab_case {
	const char *name;
	const char *stresses;
	void (*fill)(struct sky_state *s);
};

extern const struct stab_case stab_cases[];
extern const size_t stab_n_cases;

/* Medium sizes for the named cases (a few hundred ms on lavapipe) and small
 * ones for the sweeps; both keep sun, atmosphere and observer. */
void stab_medium(struct sky_state *s);
void stab_small(struct sky_state *s);

/* One random parameter set from the sweep's ranges (stab.c), small sizes,
 * with weather keys on a third of them (resolved: the state the tables
 * get); the sequence depends only on *seed, which it advances the same
 * with or without the weather. gpu_friendly keeps the
 * pipeline variants few (scattering in every constituent, a non-black
 * ground) so that a sweep on the engine does not compile a shader per case. */
void stab_random(uint64_t *seed, bool gpu_friendly, struct sky_state *ret);

/* Computes the tables in mask (and what they depend on) for s into ret as
 * RGBA doubles; tables outside the closure of mask may be left NULL.
 * Returns 0 or -errno with a message in err. */
typedef int (*stab_compute_fn)(void *ctx, const struct sky_state *s, uint32_t mask,
			       struct model_tables *ret, char *err, size_t err_size);
/* ctx unused: the double-precision model at the state's own step counts. */
int stab_model(void *ctx, const struct sky_state *s, uint32_t mask, struct model_tables *ret,
	       char *err, size_t err_size);
/* ctx is a struct eng *: the engine's tables, widened from f32 or f16. */
int stab_engine(void *ctx, const struct sky_state *s, uint32_t mask, struct model_tables *ret,
		char *err, size_t err_size);

enum stab_invariant {
	STAB_FINITE,		/* every channel of every texel finite */
	STAB_NONNEG,		/* ... and >= 0 */
	STAB_T_RANGE,		/* transmittance and every A channel in [0, 1], f_ms in [0, 1] */
	STAB_T_MONOTONE,	/* T non-increasing along a ray: table rows, rays sampled, aerial slices */
	STAB_L_MONOTONE,	/* aerial in-scattering non-decreasing with depth */
	STAB_VACUUM,		/* no scattering: L = 0 exactly; no extinction: T = 1 exactly */
	STAB_SYMMETRY,		/* mirror symmetry about the sun's vertical plane */
	STAB_SHADOWED,		/* clouds and terrain: shadowed never brighter than unshadowed */
	STAB_FIELD_SAME,	/* the cloud field's bits the same in another thread and run */
	STAB_HORIZON,		/* sky-view continuous as the sun crosses the horizon */
	STAB_N_INVARIANTS,
};
extern const char *const stab_invariant_names[STAB_N_INVARIANTS];

struct stab_result {
	uint64_t samples[STAB_N_INVARIANTS];	/* values checked */
	uint64_t fails[STAB_N_INVARIANTS];	/* values that broke the invariant */
	double max_t_ray_drop;	/* largest fall of T along a sampled ray (bilinear table) */
	double max_asym;	/* largest mirror difference / peak of the table */
	double max_jump_ratio;	/* largest horizon step / largest of the two steps either side */
	double max_psi;		/* largest multi-scattering psi_ms seen */
	double max_radiance;	/* largest sky-view or aerial radiance seen */
	char first[320];	/* the first violation: case, table, texel, values */
};

/* Tolerances: what float32 or the table sampler may legitimately add. */
struct stab_tol {
	double abs_t;		/* slack on T in [0, 1] and on monotone T along rows and slices */
	double ray_t;		/* relative slack on optical depth falling along a ray (model quadrature) */
	double sym_rel;		/* mirror difference allowed, relative to the table's peak */
};
/* stab_tol_sweep: the model without the ray check (ray_t 0), which costs
 * more than the tables of a small sweep case. */
extern const struct stab_tol stab_tol_model, stab_tol_sweep, stab_tol_f32;

/* Checks every invariant that one set of tables can show (not HORIZON) and
 * adds the counts to r; name labels the first violation. */
void stab_check(const char *name, const struct sky_state *s, const struct model_tables *m,
		const struct stab_tol *tol, struct stab_result *r);

/* Sweeps the sun from -3 to +3 degrees of elevation in 0.25 degree steps and
 * checks every sky-view row's mean radiance for a step more than 4 times the
 * largest of the two steps on either side (and above 1e-6 of the row's peak). Returns 0 or -errno. */
int stab_horizon(const char *name, stab_compute_fn fn, void *ctx, const struct sky_state *s,
		 struct stab_result *r, char *err, size_t err_size);

/* PSNR (peak = the reference's largest RGB) and the largest relative error
 * among RGB values above 1e-3 of the peak, per table; INFINITY when equal. */
void stab_compare(const struct sky_state *s, const struct model_tables *ref,
		  const struct model_tables *got, double ret_psnr_db[STATE_N_TABLES],
		  double ret_max_rel[STATE_N_TABLES]);

uint64_t stab_total_fails(const struct stab_result *r);
/* Counts one value checked for inv, and a violation when !ok (the first
 * of r described by fmt). */
void stab_note(struct stab_result *r, enum stab_invariant inv, bool ok, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));

/* ---- clouds and terrain (stab_clouds.c) ----
 * The stiff and extreme cases of the cloud layers and the terrain, as keys,
 * so that the model side (the field of proto/skycloud.h and
 * proto/skyterrain.h in double, the path tracer) and the engine's cloud
 * passes run the same cases: stab_cloud_state makes a case's state,
 * stab_cloud_check_model checks the field and the tracer,
 * stab_check_shadowed any two sets of tables, with the case's clouds and
 * terrain and the bound (stab_cloud_bound). */

#define STAB_CLOUD_KEYS 20
struct stab_cloud_case {
	const char *name;
	const char *stresses;
	/* Set in order on state_default(); "terrain=@NAME" is media.h's field. */
	const char *keys[STAB_CLOUD_KEYS];
	double utc_s;		/* the field placed at this simulated time; 0: not placed */
};
extern const struct stab_cloud_case stab_cloud_cases[];
extern const size_t stab_n_cloud_cases;

/* The state of case c (medium sizes), its field placed at c->utc_s.
 * Returns 0 or -errno with err (a key refused, a field not written). */
int stab_cloud_state(const struct stab_cloud_case *c, struct sky_state *ret, char *err,
		     size_t err_size);
/* s without cloud layers and terrain, over a white ground (albedo 1): what
 * the shadowed is compared with. The layers' shadows only take light away,
 * but the light they scatter into the air (docs/clouds.md, "In the
 * tables") makes the air over a deck brighter than over the ground, as a
 * brighter ground would, never more than a white one. */
void stab_cloud_bound(const struct sky_state *s, struct sky_state *ret);

/* The model side of a case, counted in r: the density over a grid through
 * every layer finite and in [0, extinction] (the tracer's majorant), the
 * sky occlusion in [0, 1], the clouds' transmittance toward the sun in
 * [0, 1], the terrain's height in [0, white]; the air's single scattering
 * along views up and down never brighter with the scene than without
 * (pt_shadow_pair); the tracer's radiance finite and >= 0, the same bits
 * on one thread and three; the grid's checksum (FNV-1a of the density's
 * bits) the same computed in another thread, returned in
 * *ret_checksum. Returns 0 or -errno with err. */
int stab_cloud_check_model(const char *name, const struct sky_state *s, struct stab_result *r,
			   uint64_t *ret_checksum, char *err, size_t err_size);
/* Every sky-view and aerial RGB texel of with (a state with clouds or
 * terrain) at most without's (stab_cloud_bound's) plus tol->abs_t of the
 * table's peak, finite both. */
void stab_check_shadowed(const char *name, const struct model_tables *with,
			 const struct model_tables *without, const struct stab_tol *tol,
			 struct stab_result *r);


#endif
