/* eng_params.c - what the engine uploads for a state: the uniform block
 * (struct gpu_params), the aerial views, the specialization constants of
 * each pass and the key of the kept column densities. */
#include "eng_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "skymap.h"

static bool constituent_active(const struct atmo_constituent *c)
{
	for (int i = 0; i < 3; i++)
		if (c->scattering_per_km[i] > 0.0 || c->absorption_per_km[i] > 0.0)
			return true;
	return false;
}

static bool constituent_scatters(const struct atmo_constituent *c)
{
	return c->scattering_per_km[0] > 0 || c->scattering_per_km[1] > 0 || c->scattering_per_km[2] > 0;
}

static void put4(float d[4], double a, double b, double c, double w)
{
	d[0] = (float)a;
	d[1] = (float)b;
	d[2] = (float)c;
	d[3] = (float)w;
}

static void put3(float d[3], const double v[3])
{
	for (int i = 0; i < 3; i++)
		d[i] = (float)v[i];
}

static void fill_delta(struct eng *e, const struct sky_state *s, int delta, struct gpu_params *p,
		       struct spec *base);

/* The lanes of the planet, the lights, the observer's camera and the
 * night floor: everything but the constituents. */
static void fill_scene(const struct sky_state *s, const struct state_lights *lights,
		       struct gpu_params *p)
{
	const struct atmo *a = &s->atmo;
	double fwd[3], right[3], up[3], night_cd_m2, night_gain;
	double h0 = s->altitude_km > 0.0 ? s->altitude_km : 0.0;
	double shell = a->top_radius_km - a->bottom_radius_km;

	p->BOTTOM_RADIUS_KM = (float)a->bottom_radius_km;
	p->TOP_RADIUS_KM = (float)a->top_radius_km;
	p->SHELL_KM = (float)shell;
	p->OBSERVER_KM = (float)h0;
	put4(p->albedo, a->ground_albedo[0], a->ground_albedo[1], a->ground_albedo[2], 0);
	put3(p->sun_dir, lights->sun);
	p->SUN_RADIUS_RAD = (float)(s->sun.angular_radius_deg * SKYMAP_PI / 180.0);
	put3(p->moon_dir, lights->moon);
	p->MOON_RADIUS_RAD = (float)(s->moon.angular_radius_deg * SKYMAP_PI / 180.0);
	put4(p->sun_illum, s->sun.illuminance_lx * s->sun.color[0],
	     s->sun.illuminance_lx * s->sun.color[1], s->sun.illuminance_lx * s->sun.color[2], 0);
	put4(p->moon_illum, s->moon.illuminance_lx * s->moon.color[0],
	     s->moon.illuminance_lx * s->moon.color[1], s->moon.illuminance_lx * s->moon.color[2], 0);
	state_camera_basis(&s->camera, fwd, right, up);
	put3(p->cam_fwd, fwd);
	p->CAM_TAN_HALF_VFOV = (float)tan(s->camera.vfov_deg * SKYMAP_PI / 360.0);
	put3(p->cam_right, right);
	p->CAM_ASPECT = (float)s->camera.aspect;
	put3(p->cam_up, up);
	p->AERIAL_RANGE_KM = (float)s->quality.aerial_range_km;
	p->HORIZON_COS = (float)skymap_horizon_cos(a->bottom_radius_km, h0);
	p->SKYVIEW_MIN_STEPS = (float)s->quality.skyview_min_steps;
	p->AERIAL_SQUARED = s->quality.aerial_spacing == STATE_SQUARED ? 1.0f : 0.0f;
	p->TOP_DISTANCE_KM = (float)sqrt(shell * (2.0 * a->bottom_radius_km + shell));
	state_night_floor(s, &night_cd_m2, &night_gain);
	p->night[0] = p->night[1] = p->night[2] = (float)night_cd_m2;
	p->NIGHT_GAIN = (float)night_gain;
}

void eng_fill_params(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		     struct gpu_params *p, struct spec *base)
{
	const struct atmo *a = &s->atmo;

	memset(p, 0, sizeof(*p));
	memset(base, 0, sizeof(*base));
	fill_scene(s, lights, p);

	/* Constituents that are zero everywhere are left out of the shaders. */
	double g1[ATMO_MAX_CONSTITUENTS] = { 0 };	/* by index in a */
	int n = 0;
	for (int i = 0; i < a->n_constituents; i++) {
		const struct atmo_constituent *c = &a->c[i];
		if (!constituent_active(c))
			continue;
		struct gpu_constituent *g = &p->c[n];
		const struct atmo_layer *l0 = &c->density.layers[0], *l1 = &c->density.layers[1];
		put3(g->scattering, c->scattering_per_km);
		g->PHASE_G = (float)c->g;
		struct ground_cache *gc = &e->ground[n];
		enum atmo_phase kind = constituent_scatters(c) ? c->phase : ATMO_PHASE_NONE;
		if (!gc->valid || gc->kind != kind || gc->g != c->g) {
			double excess[PHASE_GROUND_N];
			phase_ground_excess(kind, c->g, excess);
			phase_ground_fit(excess, gc->fit);
			gc->legendre[0] = phase_legendre(kind, c->g, 1);
			gc->legendre[1] = phase_legendre(kind, c->g, 2);
			gc->valid = true;
			gc->kind = kind;
			gc->g = c->g;
		}
		g1[i] = gc->legendre[0];
		put3(g->absorption, c->absorption_per_km);
		g->PHASE_G1 = (float)gc->legendre[0];
		put4(g->layer0, l0->width_km, l0->exp_term, l0->exp_scale_per_km, l0->linear_per_km);
		put4(g->layer0c_1, l0->constant, l1->exp_term, l1->exp_scale_per_km, l1->linear_per_km);
		g->LAYER1_CONSTANT = (float)l1->constant;
		g->PHASE_G2 = (float)gc->legendre[1];
		/* A constituent that scatters nothing needs no phase function. */
		base->v[SPEC_PHASE_0 + n] = constituent_scatters(c) ? (int32_t)c->phase : 0;
		for (int k = 0; k < PHASE_GROUND_FIT; k++)
			p->ground_fit[k][n] = (float)gc->fit[k];
		/* Profiles without an exponential term (ozone's tent) skip exp(). */
		if (l0->exp_term != 0.0 || l1->exp_term != 0.0)
			base->v[SPEC_EXP_MASK] |= 1 << n;
		n++;
	}
	base->v[SPEC_N_CONST] = n;
	base->v[SPEC_STORAGE_F16] = s->quality.storage == STATE_F16;
	base->v[SPEC_MOON_LIT] = s->moon.illuminance_lx > 0.0;
	base->v[SPEC_GROUND_BLACK] = a->ground_albedo[0] == 0 && a->ground_albedo[1] == 0 && a->ground_albedo[2] == 0;
	base->v[SPEC_T_W] = (int32_t)s->quality.t[STATE_TRANSMITTANCE].width;
	base->v[SPEC_T_H] = (int32_t)s->quality.t[STATE_TRANSMITTANCE].height;
	base->v[SPEC_M_W] = (int32_t)s->quality.t[STATE_MULTISCATTER].width;
	base->v[SPEC_M_H] = (int32_t)s->quality.t[STATE_MULTISCATTER].height;
	/* multiscatter_dirs=0 switches the higher orders off: sky-view and
	 * aerial perspective drop the term, and the multi-scattering table, if
	 * asked for at all, is computed with the cheapest quadrature. */
	base->v[SPEC_MS_DIRS] = s->quality.multiscatter_dirs ? (int32_t)s->quality.multiscatter_dirs : 2;
	base->v[SPEC_MULTISCATTER_ON] = s->quality.multiscatter_dirs != 0;
	/* The lobe constituent (common.glsl's ms_source) by its index among those in the shaders, plus 1. */
	int delta = s->quality.multiscatter_dirs ? phase_delta_constituent(s, g1) : -1;
	int lobe = s->quality.multiscatter_dirs ? phase_lobe_constituent(s, g1) : -1;
	if (lobe >= 0 && constituent_active(&a->c[lobe])) {
		int before = 0;
		for (int i = 0; i < lobe; i++)
			before += constituent_active(&a->c[i]);
		base->v[SPEC_MOMENT_LOBE] = before + 1;
	}
	fill_delta(e, s, delta, p, base);
}

/* Delta-M for the higher orders (common.glsl's delta_source): the
 * constituent's index among those in the shaders plus 1 in constant 23,
 * its forward fraction f and the truncated phase's g' (DELTA_F, DELTA_G), and
 * the ground's first bounce through the truncated phase, which is what
 * scatters psi_ms in the scaled medium. Kept while the phase stays (a
 * quadrature and 30000 phase evaluations, more than a sun change's tables). */
static void fill_delta(struct eng *e, const struct sky_state *s, int delta, struct gpu_params *p,
		       struct spec *base)
{
	const struct atmo *a = &s->atmo;
	if (delta < 0 || !constituent_active(&a->c[delta]))
		return;
	int n = 0;
	for (int i = 0; i < delta; i++)
		n += constituent_active(&a->c[i]);
	struct ground_cache *dc = &e->delta;
	if (!dc->valid || dc->kind != a->c[delta].phase || dc->g != a->c[delta].g) {
		double excess[PHASE_GROUND_N];
		phase_delta_truncation(a->c[delta].phase, a->c[delta].g, &dc->legendre[0], &dc->legendre[1]);
		phase_ground_excess(ATMO_PHASE_HENYEY_GREENSTEIN, dc->legendre[1], excess);
		phase_ground_fit(excess, dc->fit);
		dc->valid = true;
		dc->kind = a->c[delta].phase;
		dc->g = a->c[delta].g;
	}
	for (int k = 0; k < PHASE_GROUND_FIT; k++)
		p->ground_fit[k][n] = (float)dc->fit[k];
	p->c[n].DELTA_F = (float)dc->legendre[0];
	p->c[n].DELTA_G = (float)dc->legendre[1];
	double h, spread;
	phase_delta_peak(a->c[delta].phase, a->c[delta].g, &h, &spread);
	p->DELTA_PEAK_H = (float)h;
	p->DELTA_PEAK_SPREAD_RAD = (float)spread;
	base->v[SPEC_DELTA_LOBE] = n + 1;
}

/* ---- the aerial jobs ---- */

/* A camera's frame: forward, right, up, the field and the eye's altitude. */
static void put_camera(struct gpu_aerial_job *job, const struct aplan_camera *v)
{
	put3(job->fwd, v->fwd);
	job->tan_half_vfov = (float)v->tan_half;
	put3(job->right, v->right);
	job->aspect = (float)v->aspect;
	put3(job->up, v->up);
	job->eye_km = (float)v->h_km;
}

/* A panorama's mapping, the floats of aplan's m0 and m1 exactly. */
static void put_mapping(struct gpu_aerial_job *job, const struct aplan_panorama *o)
{
	job->azimuth0_rad = o->m0[0];
	job->azimuth_step_rad = o->m0[1];
	job->row0 = o->m0[2];
	job->row_step = o->m0[3];
	job->horizon_rad = o->m1[0];
	job->width = o->m1[1];
	job->height = o->m1[2];
	job->full_circle = o->m1[3];
}

static void put_lights(struct gpu_aerial_job *job, const struct aplan_camera *v, uint32_t out_texel,
		       uint32_t kind)
{
	put3(job->sun, v->sun);
	job->out_texel = out_texel;
	put3(job->moon, v->moon);
	job->kind = kind;
	put3(job->site_east, v->site[0]);
	put3(job->site_north, v->site[1]);
	put3(job->site_up, v->site[2]);
	job->ground_east_km = (float)v->ground_km[0];
	job->ground_north_km = (float)v->ground_km[1];
	job->ground_up_km = (float)v->ground_km[2];
}

void eng_fill_views(const struct sky_state *s, const struct aplan *p, uint64_t pano_base,
		    void *out, uint32_t *ret_march, uint32_t *ret_resample)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	uint32_t texels = q->width * q->height * q->depth, n_march = 0, n_resample = 0;
	struct gpu_aerial_head *head = out;
	struct gpu_aerial_job *jobs = (struct gpu_aerial_job *)(head + 1);
	struct gpu_aerial_job resample[APLAN_CAMERAS];

	memset(out, 0, VIEW_BUFFER_BYTES);
	for (uint32_t c = 0; c < p->n_cameras; c++) {
		if (p->volume[c] < 0 || p->panorama[c] >= 0)
			continue;
		struct gpu_aerial_job *job = &jobs[n_march++];
		put_camera(job, &p->cam[c]);
		put_lights(job, &p->cam[c], (uint32_t)p->volume[c] * texels, AERIAL_JOB_CAMERA);
	}
	for (uint32_t k = 0; k < p->n_panoramas; k++) {
		const struct aplan_panorama *o = &p->pano[k];
		const struct aplan_camera *eye = &p->cam[o->leader];
		uint32_t at = (uint32_t)(pano_base + k * aplan_panorama_texels(p));
		struct gpu_aerial_job *job = &jobs[n_march++];
		put_mapping(job, o);
		job->eye_km = (float)eye->h_km;
		put_lights(job, eye, at, AERIAL_JOB_PANORAMA);
		for (uint32_t c = 0; c < p->n_cameras; c++) {
			if (p->panorama[c] != (int32_t)k || p->volume[c] < 0)
				continue;
			struct gpu_aerial_job *r = &resample[n_resample++];
			memset(r, 0, sizeof(*r));
			put_camera(r, &p->cam[c]);
			put_mapping(r, o);
			r->out_texel = (uint32_t)p->volume[c] * texels;
			r->panorama_texel = at;
		}
	}
	head->n_march = n_march;
	memcpy(jobs + n_march, resample, n_resample * sizeof(resample[0]));
	*ret_march = n_march;
	*ret_resample = n_resample;
}

/* The constants one pass is specialized on: the others are zeroed so that a
 * change that does not concern a pass reuses its cached pipeline. The
 * grain sets the texels an invocation shares its rays between and, for
 * multi-scattering, the lanes sharing a texel and the workgroup's size. */
struct spec eng_pass_spec(const struct spec *base, const struct sky_state *s, int t,
			  const struct grain *g)
{
	struct spec k = *base;
	const struct state_table_quality *q = &s->quality.t[t];

	k.v[SPEC_OUT_W] = (int32_t)q->width;
	k.v[SPEC_OUT_H] = (int32_t)q->height;
	k.v[SPEC_OUT_D] = (int32_t)q->depth;
	k.v[SPEC_STEPS] = (int32_t)q->steps;
	if (t == STATE_TRANSMITTANCE) {
		for (int i = 0; i < 4; i++)
			k.v[SPEC_PHASE_0 + i] = 0;	/* extinction only */
		k.v[SPEC_MOON_LIT] = k.v[SPEC_GROUND_BLACK] = 0;
		k.v[SPEC_M_W] = k.v[SPEC_M_H] = k.v[SPEC_MS_DIRS] = 0;
		k.v[SPEC_STEPS] = k.v[SPEC_EXP_MASK] = 0;	/* steps and profiles: the column pass's */
	}
	if (t != STATE_MULTISCATTER)
		k.v[SPEC_MS_DIRS] = 0;
	k.v[SPEC_SV_AZ_GROUP] = t == STATE_SKYVIEW ? (int32_t)g->sv_az_group : 0;
	if (t == STATE_MULTISCATTER) {
		int32_t cells = SKY_MS_MARCHED(k.v[SPEC_MS_DIRS]);
		k.v[SPEC_MOON_LIT] = k.v[SPEC_MULTISCATTER_ON] = 0;	/* the table is the term itself */
		k.v[SPEC_MS_SUN_GROUP] = (int32_t)g->ms_sun_group;
		k.v[SPEC_MS_LANES] = g->ms_wide ? cells : 1;
		k.v[SPEC_LOCAL_X] = g->ms_wide ? cells : 8;
		k.v[SPEC_LOCAL_Y] = g->ms_wide ? 1 : 8;
	}
	if (t == STATE_TRANSMITTANCE)
		k.v[SPEC_MULTISCATTER_ON] = k.v[SPEC_MOMENT_LOBE] = k.v[SPEC_DELTA_LOBE] = 0;
	if (t == STATE_SKYVIEW || t == STATE_AERIAL) {
		k.v[SPEC_GROUND_BLACK] = 0;	/* the ground enters through the multiscatter table */
		k.v[SPEC_LOOKUP_IMAGES] = g->lookup_images;
		/* Only a table that fills the shader's block exactly: the
		 * descriptor's range is then the block's whole size. */
		k.v[SPEC_MS_UNIFORM] = t == STATE_AERIAL && g->ms_uniform && !g->lookup_images &&
				       s->quality.t[STATE_MULTISCATTER].width * s->quality.t[STATE_MULTISCATTER].height ==
					       SKY_MS_UNIFORM_TEXELS;
	} else {
		/* Only the sky's marches read the clouds. */
		k.v[SPEC_CLOUD_LAYERS] = k.v[SPEC_SHADOW_W] = k.v[SPEC_CLOUD_W] = k.v[SPEC_CLOUD_PHASES] = 0;
	}
	return k;
}

/* Which layers of the shaders' constituents have an exponential term:
 * bit 4 + n for constituent n's layer 0, bit 8 + n for its layer 1. */
static int32_t exp_layers(const struct atmo *a)
{
	int32_t bits = 0;
	int n = 0;
	for (int i = 0; i < a->n_constituents; i++) {
		const struct atmo_constituent *c = &a->c[i];
		if (!constituent_active(c))
			continue;
		for (int l = 0; l < 2; l++)
			if (c->density.layers[l].exp_term != 0.0)
				bits |= 1 << (4 + 4 * l + n);
		n++;
	}
	return bits;
}

/* The column pass is specialized on the constituents' count and profile
 * kinds (which layers are exponential: a step carries exp(k h) of those
 * only), the transmittance table's size and its steps, nothing else. */
struct spec eng_column_spec(const struct spec *base, const struct sky_state *s)
{
	const struct state_table_quality *q = &s->quality.t[STATE_TRANSMITTANCE];
	struct spec k = { { 0 } };

	k.v[SPEC_N_CONST] = base->v[SPEC_N_CONST];
	k.v[SPEC_OUT_W] = (int32_t)q->width;
	k.v[SPEC_OUT_H] = (int32_t)q->height;
	k.v[SPEC_STEPS] = (int32_t)q->steps;
	k.v[SPEC_EXP_MASK] = base->v[SPEC_EXP_MASK] | exp_layers(&s->atmo);
	return k;
}

void eng_column_key(const struct gpu_params *p, const struct spec *column_spec,
		       struct column_key *ret)
{
	memset(ret, 0, sizeof(*ret));
	memcpy(ret->planet, p->planet, sizeof(ret->planet));
	ret->h_top = p->TOP_DISTANCE_KM;
	for (int i = 0; i < column_spec->v[SPEC_N_CONST]; i++) {
		memcpy(ret->layers[i], p->c[i].layer0, 4 * sizeof(float));
		memcpy(ret->layers[i] + 4, p->c[i].layer0c_1, 4 * sizeof(float));
		memcpy(ret->layers[i] + 8, p->c[i].layer1c, 4 * sizeof(float));
	}
	ret->spec = *column_spec;
}
