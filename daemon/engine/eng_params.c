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

static void fill_delta(struct eng *e, const struct sky_state *s, int delta, struct gpu_params *p,
		       struct spec *base);

void eng_fill_params(struct eng *e, const struct sky_state *s, struct gpu_params *p, struct spec *base)
{
	const struct atmo *a = &s->atmo;
	double sun[3], moon[3], fwd[3], right[3], up[3];
	double h0 = s->altitude_km > 0.0 ? s->altitude_km : 0.0;
	double shell = a->top_radius_km - a->bottom_radius_km;

	memset(p, 0, sizeof(*p));
	memset(base, 0, sizeof(*base));
	put4(p->planet, a->bottom_radius_km, a->top_radius_km, shell, h0);
	put4(p->albedo, a->ground_albedo[0], a->ground_albedo[1], a->ground_albedo[2], 0);
	state_direction(s->sun.elevation_deg, s->sun.azimuth_deg, sun);
	state_direction(s->moon.elevation_deg, s->moon.azimuth_deg, moon);
	put4(p->sun_dir, sun[0], sun[1], sun[2], s->sun.angular_radius_deg * SKYMAP_PI / 180.0);
	put4(p->moon_dir, moon[0], moon[1], moon[2], s->moon.angular_radius_deg * SKYMAP_PI / 180.0);
	put4(p->sun_illum, s->sun.illuminance_lx * s->sun.color[0],
	     s->sun.illuminance_lx * s->sun.color[1], s->sun.illuminance_lx * s->sun.color[2], 0);
	put4(p->moon_illum, s->moon.illuminance_lx * s->moon.color[0],
	     s->moon.illuminance_lx * s->moon.color[1], s->moon.illuminance_lx * s->moon.color[2], 0);
	state_camera_basis(&s->camera, fwd, right, up);
	put4(p->cam_fwd, fwd[0], fwd[1], fwd[2], tan(s->camera.vfov_deg * SKYMAP_PI / 360.0));
	put4(p->cam_right, right[0], right[1], right[2], s->camera.aspect);
	put4(p->cam_up, up[0], up[1], up[2], s->quality.aerial_range_km);
	put4(p->misc, skymap_horizon_cos(a->bottom_radius_km, h0), s->quality.skyview_min_steps,
	     s->quality.aerial_spacing == STATE_SQUARED ? 1.0 : 0.0,
	     sqrt(shell * (2.0 * a->bottom_radius_km + shell)));

	double night_cd_m2, night_gain;
	state_night_floor(s, &night_cd_m2, &night_gain);
	put4(p->night, night_cd_m2, night_cd_m2, night_cd_m2, night_gain);

	/* Constituents that are zero everywhere are left out of the shaders. */
	double g1[ATMO_MAX_CONSTITUENTS] = { 0 };	/* by index in a */
	int n = 0;
	for (int i = 0; i < a->n_constituents; i++) {
		const struct atmo_constituent *c = &a->c[i];
		if (!constituent_active(c))
			continue;
		struct gpu_constituent *g = &p->c[n];
		const struct atmo_layer *l0 = &c->density.layers[0], *l1 = &c->density.layers[1];
		put4(g->scattering, c->scattering_per_km[0], c->scattering_per_km[1],
		     c->scattering_per_km[2], c->g);
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
		put4(g->absorption, c->absorption_per_km[0], c->absorption_per_km[1],
		     c->absorption_per_km[2], gc->legendre[0]);
		put4(g->layer0, l0->width_km, l0->exp_term, l0->exp_scale_per_km, l0->linear_per_km);
		put4(g->layer0c_1, l0->constant, l1->exp_term, l1->exp_scale_per_km, l1->linear_per_km);
		put4(g->layer1c, l1->constant, gc->legendre[1], 0, 0);
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
 * its forward fraction f and the truncated phase's g' in layer1c.zw, and
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
	p->c[n].layer1c[2] = (float)dc->legendre[0];
	p->c[n].layer1c[3] = (float)dc->legendre[1];
	double h, spread;
	phase_delta_peak(a->c[delta].phase, a->c[delta].g, &h, &spread);
	put4(p->delta_peak, h, spread, 0, 0);
	base->v[SPEC_DELTA_LOBE] = n + 1;
}

/* ---- the aerial jobs ---- */

/* One aerial volume as the shaders see it: its eye's altitude and
 * horizontal position, its camera, and the lights in its eye's local
 * frame. */
struct volume {
	double h_km, east_km, north_km;
	double fwd[3], right[3], up[3];
	double tan_half, aspect;
	double sun[3], moon[3];
};

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double a[3], const double b[3], double ret[3])
{
	ret[0] = a[1] * b[2] - a[2] * b[1];
	ret[1] = a[2] * b[0] - a[0] * b[2];
	ret[2] = a[0] * b[1] - a[1] * b[0];
}

static void normalize3(double v[3])
{
	double n = sqrt(dot3(v, v));
	for (int i = 0; i < 3; i++)
		v[i] /= n;
}

/* The rotation from the site's local frame (east, north, up) to the one at
 * east_km, north_km from it along the ground (state_view): the local
 * vertical there, and true north for a site at lat_deg on a sphere of
 * bottom_radius_km. */
static void view_frame(double lat_deg, double bottom_radius_km, double east_km, double north_km,
		    double ret[3][3])
{
	const double deg = SKYMAP_PI / 180.0;
	double phi = lat_deg * deg, d = hypot(east_km, north_km), beta = atan2(east_km, north_km);
	double theta = d / bottom_radius_km;
	/* Earth-fixed axes: x to the site's meridian, z to the pole. */
	double u0[3] = { cos(phi), 0, sin(phi) }, e0[3] = { 0, 1, 0 }, n0[3] = { -sin(phi), 0, cos(phi) };
	double up[3], east[3], north[3], pole[3] = { 0, 0, 1 };
	for (int i = 0; i < 3; i++)
		up[i] = cos(theta) * u0[i] + sin(theta) * (sin(beta) * e0[i] + cos(beta) * n0[i]);
	cross3(pole, up, east);
	if (dot3(east, east) < 1e-18) {
		/* At a pole north has no direction: the site's north carried
		 * along the great circle, which is where the path arrives from. */
		double t[3];
		for (int i = 0; i < 3; i++)
			t[i] = cos(theta) * (sin(beta) * e0[i] + cos(beta) * n0[i]) - sin(theta) * u0[i];
		double side[3];
		cross3(up, t, side);	/* left of the path */
		for (int i = 0; i < 3; i++)
			north[i] = cos(beta) * t[i] + sin(beta) * side[i];
		cross3(north, up, east);
	}
	normalize3(east);
	cross3(up, east, north);
	/* Row r, column c: local axis r on the site's axis c (east, north, up). */
	const double *local[3] = { east, north, up }, *site[3] = { e0, n0, u0 };
	for (int r = 0; r < 3; r++)
		for (int c = 0; c < 3; c++)
			ret[r][c] = dot3(local[r], site[c]);
}

static void rotate(const double m[3][3], const double v[3], double ret[3])
{
	for (int r = 0; r < 3; r++)
		ret[r] = m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2];
}

/* Volume i of s: 0 the state's camera, then the views. */
static void volume_of(const struct sky_state *s, uint32_t i, struct volume *ret)
{
	const struct state_camera *c = i ? &s->views[i - 1].camera : &s->camera;
	double h = i && !isnan(s->views[i - 1].altitude_km) ? s->views[i - 1].altitude_km : s->altitude_km;
	double sun[3], moon[3];

	memset(ret, 0, sizeof(*ret));
	ret->h_km = h > 0.0 ? h : 0.0;
	ret->east_km = i ? s->views[i - 1].east_km : 0.0;
	ret->north_km = i ? s->views[i - 1].north_km : 0.0;
	state_camera_basis(c, ret->fwd, ret->right, ret->up);
	ret->tan_half = tan(c->vfov_deg * SKYMAP_PI / 360.0);
	ret->aspect = c->aspect;
	state_direction(s->sun.elevation_deg, s->sun.azimuth_deg, sun);
	state_direction(s->moon.elevation_deg, s->moon.azimuth_deg, moon);
	if (ret->east_km == 0.0 && ret->north_km == 0.0) {
		memcpy(ret->sun, sun, sizeof(sun));
		memcpy(ret->moon, moon, sizeof(moon));
		return;
	}
	double m[3][3];
	view_frame(s->clock.lat_deg, s->atmo.bottom_radius_km, ret->east_km, ret->north_km, m);
	rotate(m, sun, ret->sun);
	rotate(m, moon, ret->moon);
}

static bool same_eye(const struct volume *a, const struct volume *b)
{
	return a->h_km == b->h_km && a->east_km == b->east_km && a->north_km == b->north_km;
}

/* The panorama's columns and rows for s's aerial size: three quarters of
 * one volume's columns, half its rows (48 x 16 for 32 x 32), which holds
 * tests/test_views.c's goal; 64 x 16 brings the 99th percentile of the
 * error on Mars from 9.2 to 7.3 % for a third more march
 * (docs/findings.md). Never fewer than 48 x 16: the error is set by the
 * sky's curvature between the panorama's rays, not by the volume's size
 * (16 x 16 volumes from a 24 x 8 panorama read 2.8 % on average). */
static void panorama_size(const struct sky_state *s, uint32_t *ret_w, uint32_t *ret_h)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	uint32_t h = q->height / 2 > 16 ? q->height / 2 : 16;
	uint32_t w = 3 * q->width * q->height / (4 * h);
	*ret_w = w > 48 ? w : 48;
	*ret_h = h;
}

uint32_t eng_aerial_march_rows(const struct sky_state *s)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	uint32_t w, h;
	panorama_size(s, &w, &h);
	uint32_t rows = (w * h + q->width - 1) / q->width;
	return s->n_views && rows > q->height ? rows : q->height;
}

uint64_t eng_panorama_texels(const struct sky_state *s)
{
	uint32_t w, h;
	panorama_size(s, &w, &h);
	return (uint64_t)(1 + s->n_views) / 2 * w * h * s->quality.t[STATE_AERIAL].depth;
}

static float uint_bits(uint32_t u)
{
	float f;
	memcpy(&f, &u, sizeof(f));
	return f;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* The azimuths and elevations of the column centres on the border of
 * volumes vol[i], i in members (a mask), as aerial_resample.comp places
 * them: a pinhole's directions cover the azimuths and elevations of its
 * border, unless the zenith or the nadir is inside, which sets
 * *ret_pole (1 zenith, -1 nadir; the full circle of azimuths). */
static uint32_t column_directions(const struct sky_state *s, const struct volume *vol,
				  uint32_t members, double *az, double *el, int *ret_pole)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	uint32_t n = 0;
	for (uint32_t i = 0; i < AERIAL_VOLUMES; i++) {
		if (!(members & (1u << i)))
			continue;
		const struct volume *v = &vol[i];
		for (int pole = -1; pole <= 1; pole += 2) {
			double f = pole * v->fwd[2], nx = pole * v->right[2] / (f * v->tan_half * v->aspect);
			double ny = pole * v->up[2] / (f * v->tan_half);
			if (f > 0 && fabs(nx) <= 1.0 - 1.0 / q->width && fabs(ny) <= 1.0 - 1.0 / q->height)
				*ret_pole = pole;
		}
		for (uint32_t y = 0; y < q->height; y++) {
			bool edge = y == 0 || y + 1 == q->height;
			for (uint32_t x = 0; x < q->width; x += edge || q->width < 2 ? 1 : q->width - 1) {
				double nx = (x + 0.5) / q->width * 2.0 - 1.0, ny = (y + 0.5) / q->height * 2.0 - 1.0;
				double d[3];
				for (int k = 0; k < 3; k++)
					d[k] = v->fwd[k] + nx * v->tan_half * v->aspect * v->right[k] +
					       ny * v->tan_half * v->up[k];
				normalize3(d);
				az[n] = atan2(d[0], d[1]);
				el[n++] = asin(d[2] < -1.0 ? -1.0 : d[2] > 1.0 ? 1.0 : d[2]);
			}
		}
	}
	return n;
}

/* The panorama of the volumes in members, all on the eye of vol[first]:
 * its columns cover the arc of azimuths their column centres span (or the
 * full circle, from the sun's azimuth, when that is finer), its rows
 * their elevations, packed toward the eye's horizon, where the ground
 * cuts the rays short. Fills the mapping's two vec4s (aerial.comp). */
static void panorama_mapping(const struct sky_state *s, const struct volume *vol, uint32_t members,
			     uint32_t first, float m0[4], float m1[4])
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	size_t cap = (size_t)2 * (q->width + q->height) * AERIAL_VOLUMES;
	double *az = malloc(2 * cap * sizeof(double)), *el = az ? az + cap : NULL;
	uint32_t pw, ph, n = 0;
	/* Without the memory to place the columns: every direction. */
	double two_pi = 2.0 * SKYMAP_PI, start = 0.0, span = two_pi;
	double el_lo = -0.5 * SKYMAP_PI, el_hi = 0.5 * SKYMAP_PI;
	const struct volume *v = &vol[first];

	panorama_size(s, &pw, &ph);
	int pole = 0;
	if (az)
		n = column_directions(s, vol, members, az, el, &pole);
	if (n > 0) {
		el_lo = el_hi = el[0];
		for (uint32_t i = 1; i < n; i++) {
			el_lo = fmin(el_lo, el[i]);
			el_hi = fmax(el_hi, el[i]);
		}
		el_lo = pole < 0 ? -0.5 * SKYMAP_PI : el_lo;
		el_hi = pole > 0 ? 0.5 * SKYMAP_PI : el_hi;
		qsort(az, n, sizeof(double), cmp_double);
		double gap = az[0] + two_pi - az[n - 1];
		start = az[0];
		for (uint32_t i = 1; i < n; i++)
			if (az[i] - az[i - 1] > gap) {
				gap = az[i] - az[i - 1];
				start = az[i];
			}
		span = pole ? two_pi : two_pi - gap;
	}
	free(az);
	bool full = two_pi / pw <= span / (pw - 1);
	if (full)
		put4(m0, atan2(v->sun[0], v->sun[1]), two_pi / pw, 0, 0);
	else
		put4(m0, start, fmax(span / (pw - 1), 1e-6), 0, 0);
	double rb = s->atmo.bottom_radius_km;
	double el_h = -acos(rb / (rb + v->h_km));
	double e_lo = el_lo - el_h, e_hi = el_hi - el_h;
	double x_lo = copysign(sqrt(fabs(e_lo)), e_lo), x_hi = copysign(sqrt(fabs(e_hi)), e_hi);
	m0[2] = (float)x_lo;
	m0[3] = (float)fmax((x_hi - x_lo) / (ph - 1), 1e-6);
	put4(m1, el_h, pw, ph, full ? 1.0 : 0.0);
}

/* A camera's job vec4s: forward, right, up (w: tan of half the field,
 * aspect, the eye's altitude). */
static void put_camera(float *job, const struct volume *v)
{
	put4(job, v->fwd[0], v->fwd[1], v->fwd[2], v->tan_half);
	put4(job + 4, v->right[0], v->right[1], v->right[2], v->aspect);
	put4(job + 8, v->up[0], v->up[1], v->up[2], v->h_km);
}

static void put_lights(float *job, const struct volume *v, uint32_t out_texel, int kind)
{
	put4(job + 12, v->sun[0], v->sun[1], v->sun[2], 0);
	job[15] = uint_bits(out_texel);
	put4(job + 16, v->moon[0], v->moon[1], v->moon[2], kind);
}

void eng_fill_views(const struct sky_state *s, bool share, float *out, uint32_t *ret_march,
		    uint32_t *ret_resample)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	const int stride = 4 * AERIAL_JOB_VEC4;
	uint32_t texels = q->width * q->height * q->depth, n_vol = 1 + s->n_views;
	struct volume vol[AERIAL_VOLUMES];
	uint32_t group[AERIAL_VOLUMES] = { 0 };	/* members of the group volume i leads */
	uint32_t grouped = 0, n_march = 0, n_resample = 0, n_pano = 0, pw, ph;
	float resample[AERIAL_VOLUMES][4 * AERIAL_JOB_VEC4];

	panorama_size(s, &pw, &ph);
	memset(out, 0, VIEW_BUFFER_BYTES);
	for (uint32_t i = 0; i < n_vol; i++)
		volume_of(s, i, &vol[i]);
	for (uint32_t i = 0; i < n_vol; i++) {
		if (grouped & (1u << i))
			continue;
		for (uint32_t j = i; j < n_vol; j++)
			if (!(grouped & (1u << j)) && same_eye(&vol[i], &vol[j]) && (j == i || share)) {
				group[i] |= 1u << j;
				grouped |= 1u << j;
			}
	}
	for (uint32_t i = 0; i < n_vol; i++) {
		if (!group[i])
			continue;
		float *job = out + 4 + stride * n_march++;
		if (!(group[i] & (group[i] - 1))) {	/* alone: its own march */
			put_camera(job, &vol[i]);
			put_lights(job, &vol[i], i * texels, AERIAL_JOB_CAMERA);
			continue;
		}
		uint32_t pano = n_vol * texels + n_pano++ * pw * ph * q->depth;
		panorama_mapping(s, vol, group[i], i, job, job + 4);
		put4(job + 8, 0, 0, 0, vol[i].h_km);
		put_lights(job, &vol[i], pano, AERIAL_JOB_PANORAMA);
		for (uint32_t j = i; j < n_vol; j++) {
			if (!(group[i] & (1u << j)))
				continue;
			float *r = resample[n_resample++];
			memset(r, 0, sizeof(resample[0]));
			put_camera(r, &vol[j]);
			memcpy(r + 12, job, 8 * sizeof(float));
			r[20] = uint_bits(j * texels);
			r[21] = uint_bits(pano);
		}
	}
	out[0] = (float)n_march;
	memcpy(out + 4 + stride * n_march, resample, n_resample * sizeof(resample[0]));
	*ret_march = n_march;
	*ret_resample = n_resample;
}

/* The constants one pass is specialized on: the others are zeroed so that a
 * change that does not concern a pass reuses its cached pipeline. */
struct spec eng_pass_spec(const struct spec *base, const struct sky_state *s, int t)
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
	k.v[SPEC_MS_SUN_GROUP] = t == STATE_MULTISCATTER ? MS_SUN_GROUP : 0;
	k.v[SPEC_SV_AZ_GROUP] = t == STATE_SKYVIEW ? SV_AZ_GROUP : 0;
	if (t == STATE_MULTISCATTER)
		k.v[SPEC_MOON_LIT] = k.v[SPEC_MULTISCATTER_ON] = 0;	/* the table is the term itself */
	if (t == STATE_TRANSMITTANCE)
		k.v[SPEC_MULTISCATTER_ON] = k.v[SPEC_MOMENT_LOBE] = k.v[SPEC_DELTA_LOBE] = 0;
	if (t == STATE_SKYVIEW || t == STATE_AERIAL)
		k.v[SPEC_GROUND_BLACK] = 0;	/* the ground enters through the multiscatter table */
	return k;
}

/* The column pass is specialized on the constituents' count and profile
 * kinds, the transmittance table's size and its steps, nothing else. */
struct spec eng_column_spec(const struct spec *base, const struct sky_state *s)
{
	const struct state_table_quality *q = &s->quality.t[STATE_TRANSMITTANCE];
	struct spec k = { { 0 } };

	k.v[SPEC_N_CONST] = base->v[SPEC_N_CONST];
	k.v[SPEC_OUT_W] = (int32_t)q->width;
	k.v[SPEC_OUT_H] = (int32_t)q->height;
	k.v[SPEC_STEPS] = (int32_t)q->steps;
	k.v[SPEC_EXP_MASK] = base->v[SPEC_EXP_MASK];
	return k;
}

void eng_column_key(const struct gpu_params *p, const struct spec *column_spec,
		       struct column_key *ret)
{
	memset(ret, 0, sizeof(*ret));
	memcpy(ret->planet, p->planet, sizeof(ret->planet));
	ret->h_top = p->misc[3];
	for (int i = 0; i < column_spec->v[SPEC_N_CONST]; i++) {
		memcpy(ret->layers[i], p->c[i].layer0, 4 * sizeof(float));
		memcpy(ret->layers[i] + 4, p->c[i].layer0c_1, 4 * sizeof(float));
		memcpy(ret->layers[i] + 8, p->c[i].layer1c, 4 * sizeof(float));
	}
	ret->spec = *column_spec;
}
