/* stab.c - the named stiff cases, the seeded sweep and the table invariants,
 * shared by the numerical tests and skybench stability. */
#include "stab.h"

#include <assert.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "eng.h"
#include "skymap.h"

const char *const stab_invariant_names[STAB_N_INVARIANTS] = {
	"finite", "non-negative", "T, A, f_ms in [0, 1]", "T monotone along rays",
	"aerial L monotone", "vacuum exact", "symmetry", "shadowed <= unshadowed", "field the same",
	"horizon continuity",
};

/* Float32 tables: the slack covers rounding of exp, and in the mirror test
 * the float32 geometry of rays that graze the horizon (2e-4 of the peak
 * seen in the sweep, where the model is symmetric to 1e-15). The ray check
 * runs on the double-precision quadrature in both cases; 1e-4 is what 512
 * equal steps leave along a ray that grazes a 10 km planet. */
const struct stab_tol stab_tol_model = { .abs_t = 1e-12, .ray_t = 1e-4, .sym_rel = 1e-9 };
const struct stab_tol stab_tol_sweep = { .abs_t = 1e-12, .ray_t = 0, .sym_rel = 1e-9 };
const struct stab_tol stab_tol_f32 = { .abs_t = 2e-6, .ray_t = 1e-4, .sym_rel = 1e-3 };

/* Cases -------------------------------------------------------------------- */

/* Keys of the cases are fixed strings: a refusal is a bug of this file. */
static void set(struct sky_state *s, const char *pair)
{
	char err[256];
	int rc = state_set_pair(s, pair, NULL, err, sizeof(err));
	if (rc < 0)
		fprintf(stderr, "stab: %s\n", err);
	assert(rc == 0);
}

static void setf(struct sky_state *s, const char *key, double v)
{
	char pair[128];
	snprintf(pair, sizeof(pair), "%s=%.17g", key, v);
	set(s, pair);
}

/* Scales scattering (and the absorption of the aerosol) of every
 * constituent by k: more matter per km, same profiles. */
static void scale_coefficients(struct sky_state *s, double k, bool absorption)
{
	for (int i = 0; i < s->atmo.n_constituents; i++)
		for (int ch = 0; ch < 3; ch++) {
			s->atmo.c[i].scattering_per_km[ch] *= k;
			if (absorption)
				s->atmo.c[i].absorption_per_km[ch] *= k;
		}
}

static void c_earth(struct sky_state *s) { (void)s; }
static void c_vacuum(struct sky_state *s)
{
	set(s, "rayleigh_scattering_per_km=0");
	set(s, "mie_scattering_per_km=0");
	set(s, "mie_absorption_per_km=0");
	set(s, "ozone_absorption_per_km=0");
}
static void c_absorption_only(struct sky_state *s)
{
	set(s, "rayleigh_scattering_per_km=0");
	set(s, "mie_scattering_per_km=0");
	set(s, "mie_absorption_per_km=0");
	for (int ch = 0; ch < 3; ch++)
		s->atmo.c[ATMO_OZONE].absorption_per_km[ch] *= 10.0;
}
static void c_thin(struct sky_state *s) { scale_coefficients(s, 0.01, true); }
static void c_x10(struct sky_state *s) { scale_coefficients(s, 10.0, false); }
static void c_x100(struct sky_state *s) { scale_coefficients(s, 100.0, false); }
static void c_mars(struct sky_state *s) { set(s, "preset=mars"); }
static void c_titan(struct sky_state *s)
{
	/* Haze: vertical optical depth 4 over a 60 km scale height, single
	 * scattering albedo 0.93, g 0.6. */
	double haze = 4.0 / 60.0;
	set(s, "bottom_radius_km=2575");
	set(s, "top_radius_km=3175");
	scale_coefficients(s, 1.0, false);
	for (int ch = 0; ch < 3; ch++) {
		s->atmo.c[ATMO_RAYLEIGH].scattering_per_km[ch] *= 4.4;
		s->atmo.c[ATMO_MIE].scattering_per_km[ch] = haze * 0.93;
		s->atmo.c[ATMO_MIE].absorption_per_km[ch] = haze * 0.07;
		s->atmo.c[ATMO_OZONE].absorption_per_km[ch] = 0;
	}
	set(s, "rayleigh_scale_height_km=60");
	set(s, "mie_scale_height_km=60");
	set(s, "mie_g=0.6");
}
static void c_g099(struct sky_state *s) { set(s, "mie_g=0.99"); set(s, "sun_elevation_deg=10"); }
static void c_g0999(struct sky_state *s) { set(s, "mie_g=0.999"); set(s, "sun_elevation_deg=10"); }
static void c_gm099(struct sky_state *s) { set(s, "mie_g=-0.99"); set(s, "sun_elevation_deg=10"); }
static void c_tiny(struct sky_state *s)
{
	set(s, "bottom_radius_km=10");
	set(s, "top_radius_km=110");
}
static void c_plane(struct sky_state *s)
{
	/* Rayleigh only, vertical optical depth 0.1 in every channel. */
	set(s, "bottom_radius_km=1000000");
	set(s, "top_radius_km=1000100");
	set(s, "mie_scattering_per_km=0");
	set(s, "mie_absorption_per_km=0");
	set(s, "ozone_absorption_per_km=0");
	setf(s, "rayleigh_scattering_per_km", 0.1 / (8.0 * (1.0 - exp(-100.0 / 8.0))));
}
static void c_obs_0(struct sky_state *s) { set(s, "altitude_km=0"); }
static void c_obs_m1(struct sky_state *s) { set(s, "altitude_km=-0.001"); }
static void c_obs_1m(struct sky_state *s) { set(s, "altitude_km=0.001"); }
static void c_obs_1km(struct sky_state *s) { set(s, "altitude_km=1"); }
static void c_obs_100(struct sky_state *s) { set(s, "altitude_km=100"); }
static void c_obs_1e4(struct sky_state *s) { set(s, "altitude_km=10000"); set(s, "camera_pitch_deg=-60"); }
static void c_obs_1e6(struct sky_state *s) { set(s, "altitude_km=1000000"); set(s, "camera_pitch_deg=-90"); }
static void giant(struct sky_state *s)
{
	set(s, "top_radius_km=70100");
	set(s, "bottom_radius_km=70000");
}
static void c_giant_1m(struct sky_state *s) { giant(s); set(s, "altitude_km=0.001"); }
static void c_giant_1km(struct sky_state *s) { giant(s); set(s, "altitude_km=1"); }
static void c_sun_90(struct sky_state *s) { set(s, "sun_elevation_deg=90"); }
static void c_sun_0(struct sky_state *s) { set(s, "sun_elevation_deg=0"); }
static void c_sun_m083(struct sky_state *s) { set(s, "sun_elevation_deg=-0.83"); }
static void c_sun_m6(struct sky_state *s) { set(s, "sun_elevation_deg=-6"); }
static void c_sun_m18(struct sky_state *s) { set(s, "sun_elevation_deg=-18"); }
static void c_sun_m90(struct sky_state *s) { set(s, "sun_elevation_deg=-90"); }
/* The aerial camera's middle row (odd height) looks exactly along its
 * pitch: at the ground, pitch 0 is the horizon; 5.7296e-6 degrees is a
 * cosine of 1e-7 from it. */
static void horizon_view(struct sky_state *s, double pitch_deg)
{
	set(s, "altitude_km=0");
	set(s, "sun_elevation_deg=3");
	setf(s, "camera_pitch_deg", pitch_deg);
	set(s, "aerial_height=17");
}
static void c_view_h(struct sky_state *s) { horizon_view(s, 0.0); }
static void c_view_hp(struct sky_state *s) { horizon_view(s, asin(1e-7) * 180.0 / M_PI); }
static void c_view_hm(struct sky_state *s) { horizon_view(s, -asin(1e-7) * 180.0 / M_PI); }

/* Weather cases: the keys, then the state the tables are computed with
 * (state_resolve), so that the model, the engine and the invariants all
 * see the weathered atmosphere. */
static void weathered(struct sky_state *s)
{
	char err[256];
	int rc = state_resolve(s, s, NULL, err, sizeof(err));
	if (rc < 0)
		fprintf(stderr, "stab: %s\n", err);
	assert(rc == 0);
}
static void c_fog(struct sky_state *s)
{
	set(s, "visibility_km=0.05");
	set(s, "aerosol=maritime");
	set(s, "relative_humidity=1");
	weathered(s);
}
static void c_vis_300(struct sky_state *s) { set(s, "visibility_km=300"); weathered(s); }
static void c_rh_100(struct sky_state *s)
{
	set(s, "relative_humidity=1");
	set(s, "aerosol=maritime");
	weathered(s);
}
static void c_ozone_0(struct sky_state *s) { set(s, "ozone_du=0"); weathered(s); }
static void c_ozone_600(struct sky_state *s) { set(s, "ozone_du=600"); set(s, "sun_elevation_deg=-3"); weathered(s); }
static void c_dust(struct sky_state *s)
{
	set(s, "visibility_km=0.2");
	set(s, "aerosol=desert");
	set(s, "relative_humidity=0.1");
	weathered(s);
}

const struct stab_case stab_cases[] = {
	{ "earth", "reference", c_earth },
	{ "vacuum", "L = 0, T = 1 exactly, no 0/0", c_vacuum },
	{ "absorption only", "ozone x10, no scattering: L = 0, T = exp(-tau)", c_absorption_only },
	{ "thin x0.01", "cancellation in the segment integral", c_thin },
	{ "scattering x10", "T underflow near the horizon, f_ms -> 1", c_x10 },
	{ "scattering x100", "T underflow near the horizon, f_ms -> 1", c_x100 },
	{ "mars", "red Rayleigh, larger H / R", c_mars },
	{ "titan-like", "optically thick everywhere (haze tau 4, g 0.6)", c_titan },
	{ "g 0.99", "phase normalization, HG denominator", c_g099 },
	{ "g 0.999", "phase normalization, HG denominator", c_g0999 },
	{ "g -0.99", "backward peak", c_gm099 },
	{ "planet 10 km, shell 100 km", "extreme curvature", c_tiny },
	{ "plane-parallel 1e6 km, tau 0.1", "flat limit", c_plane },
	{ "observer 0 m", "exactly on the ground", c_obs_0 },
	{ "observer -1 m", "clamped to the ground", c_obs_m1 },
	{ "observer 1 m", "altitude apart from radius", c_obs_1m },
	{ "observer 1 km", "reference for 1 m", c_obs_1km },
	{ "observer 100 km", "at the top", c_obs_100 },
	{ "observer 1e4 km", "in space", c_obs_1e4 },
	{ "observer 1e6 km", "far out, rays miss the shell", c_obs_1e6 },
	{ "70000 km planet, 1 m", "altitude apart from radius", c_giant_1m },
	{ "70000 km planet, 1 km", "reference for 1 m", c_giant_1km },
	{ "sun zenith", "sun at 90", c_sun_90 },
	{ "sun horizon", "sun at 0", c_sun_0 },
	{ "sun -0.83", "sunset", c_sun_m083 },
	{ "sun -6", "civil twilight", c_sun_m6 },
	{ "sun -18", "night", c_sun_m18 },
	{ "sun nadir", "sun at -90", c_sun_m90 },
	{ "view at horizon", "sky/ground switch", c_view_h },
	{ "view horizon +1e-7", "discriminant near 0", c_view_hp },
	{ "view horizon -1e-7", "discriminant near 0", c_view_hm },
	{ "fog 50 m", "maritime aerosol at saturation, tau 68, g 0.83", c_fog },
	{ "visibility 300 km", "no aerosol left: air alone", c_vis_300 },
	{ "humidity 100 %", "maritime climatology grown 6 times", c_rh_100 },
	{ "ozone 0 DU", "no ozone absorption", c_ozone_0 },
	{ "ozone 600 DU", "twice Earth's ozone, sun -3 (Chappuis band)", c_ozone_600 },
	{ "dust storm 200 m", "desert aerosol, tau 37, absorbing", c_dust },
};
const size_t stab_n_cases = sizeof(stab_cases) / sizeof(stab_cases[0]);

static void set_quality(struct sky_state *s, uint32_t tw, uint32_t th, uint32_t ts, uint32_t mw,
			uint32_t ms, uint32_t dirs, uint32_t sw, uint32_t sh, uint32_t ss, uint32_t aw,
			uint32_t ad, uint32_t as)
{
	struct state_quality *q = &s->quality;
	q->t[STATE_TRANSMITTANCE] = (struct state_table_quality){ tw, th, 1, ts };
	q->t[STATE_MULTISCATTER] = (struct state_table_quality){ mw, mw, 1, ms };
	q->t[STATE_SKYVIEW] = (struct state_table_quality){ sw, sh, 1, ss };
	/* An odd aerial height set by a case (the horizon views) is kept. */
	uint32_t ah = q->t[STATE_AERIAL].height % 2 ? q->t[STATE_AERIAL].height : aw;
	q->t[STATE_AERIAL] = (struct state_table_quality){ aw, ah, ad, as };
	q->multiscatter_dirs = dirs;
	q->skyview_min_steps = ss < 4 ? ss : 4;
	/* The night-sky floor is light from beyond the atmosphere, added to the
	 * tables; the invariants (L = 0 without scattering) are about the
	 * atmosphere, so every case runs without it. */
	s->night.zenith_luminance_cd_m2 = 0.0;
}

void stab_medium(struct sky_state *s)
{
	set_quality(s, 64, 32, 20, 16, 10, 64, 64, 36, 16, 16, 16, 2);
}

void stab_small(struct sky_state *s)
{
	set_quality(s, 16, 8, 8, 8, 8, 2, 16, 8, 8, 4, 4, 2);
	s->quality.skyview_min_steps = 2;
}

/* splitmix64: a fixed seed gives the same sweep on every machine. */
static uint64_t next_u64(uint64_t *seed)
{
	uint64_t z = (*seed += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

static double uniform(uint64_t *seed, double lo, double hi)
{
	return lo + (hi - lo) * ((next_u64(seed) >> 11) * (1.0 / 9007199254740992.0));
}

static double log_uniform(uint64_t *seed, double lo, double hi)
{
	return pow(10.0, uniform(seed, log10(lo), log10(hi)));
}

static void exp_density(struct atmo_profile *p, double scale_height_km)
{
	*p = (struct atmo_profile){ 0 };
	p->layers[1].exp_term = 1.0;
	p->layers[1].exp_scale_per_km = -1.0 / scale_height_km;
}

/* Weather keys on a third of the sweep's atmospheres, each key given or
 * not at even odds, over its whole range; then the state the tables get. */
static void random_weather(uint64_t *seed, struct sky_state *s)
{
	static const char *const aerosols[] = { "clean", "continental", "urban", "maritime", "desert" };
	char pair[64];

	if (uniform(seed, 0, 1) >= 1.0 / 3.0)
		return;
	if (uniform(seed, 0, 1) < 0.5)
		setf(s, "visibility_km", log_uniform(seed, WEATHER_VISIBILITY_MIN_KM, WEATHER_VISIBILITY_MAX_KM));
	if (uniform(seed, 0, 1) < 0.5)
		setf(s, "relative_humidity", uniform(seed, 0, 1));
	if (uniform(seed, 0, 1) < 0.5) {
		snprintf(pair, sizeof(pair), "aerosol=%s", aerosols[next_u64(seed) % 5]);
		set(s, pair);
	}
	if (uniform(seed, 0, 1) < 0.5)
		setf(s, "angstrom_beta", log_uniform(seed, 1e-3, WEATHER_ANGSTROM_BETA_MAX));
	if (uniform(seed, 0, 1) < 0.5)
		setf(s, "ozone_du", uniform(seed, 0, WEATHER_OZONE_DU_MAX));
	if (uniform(seed, 0, 1) < 0.5)
		setf(s, "cloud_oktas", uniform(seed, 0, WEATHER_OKTAS_MAX));
	weathered(s);
}

void stab_random(uint64_t *seed, bool gpu_friendly, struct sky_state *ret)
{
	struct sky_state s;
	state_default(&s);
	stab_small(&s);
	struct atmo *a = &s.atmo;

	a->bottom_radius_km = log_uniform(seed, 1.0, 70000.0);
	a->top_radius_km = a->bottom_radius_km + log_uniform(seed, 1.0, 5000.0);
	double shell = a->top_radius_km - a->bottom_radius_km;
	for (int i = 0; i < 3; i++) {
		struct atmo_constituent *c = &a->c[i];
		exp_density(&c->density, log_uniform(seed, 0.1, 100.0));
		double one = log_uniform(seed, 1e-7, 10.0);
		for (int ch = 0; ch < 3; ch++) {
			double k = i == ATMO_MIE ? one : log_uniform(seed, 1e-7, 10.0);
			c->scattering_per_km[ch] = i == ATMO_OZONE ? 0.0 : k;
			c->absorption_per_km[ch] = i == ATMO_RAYLEIGH ? 0.0
						   : i == ATMO_MIE ? k * log_uniform(seed, 1e-3, 1.0) : k;
		}
		/* A constituent that is zero everywhere: no 0/0 where it is left out. */
		if (!gpu_friendly && uniform(seed, 0, 1) < 0.1)
			for (int ch = 0; ch < 3; ch++)
				c->scattering_per_km[ch] = c->absorption_per_km[ch] = 0.0;
	}
	a->c[ATMO_MIE].g = uniform(seed, -0.999, 0.999);
	a->c[ATMO_MIE].phase = uniform(seed, 0, 1) < 0.5 ? ATMO_PHASE_CORNETTE_SHANKS
							 : ATMO_PHASE_HENYEY_GREENSTEIN;
	for (int ch = 0; ch < 3; ch++)
		a->ground_albedo[ch] = uniform(seed, 0.0, 1.0);
	if (!gpu_friendly && uniform(seed, 0, 1) < 0.1)
		a->ground_albedo[0] = a->ground_albedo[1] = a->ground_albedo[2] = 0.0;

	double u = uniform(seed, 0, 1);
	s.sun.elevation_deg = u < 0.1 ? 0.0 : u < 0.13 ? 90.0 : u < 0.16 ? -90.0 : uniform(seed, -90, 90);
	/* Multiples of 180 / W put the sun's vertical plane between two texel
	 * columns of the sky-view table, where mirror symmetry is exact. */
	uint32_t w = s.quality.t[STATE_SKYVIEW].width;
	s.sun.azimuth_deg = (double)(next_u64(seed) % (2 * w)) * 180.0 / w;

	u = uniform(seed, 0, 1);
	s.altitude_km = u < 0.15   ? 0.0
			: u < 0.2  ? -uniform(seed, 0, 1)
			: u < 0.5  ? uniform(seed, 0, shell)
			: u < 0.6  ? shell
				   : shell + log_uniform(seed, 1e-3, 1e6);
	s.camera.yaw_deg = s.sun.azimuth_deg;
	s.camera.pitch_deg = uniform(seed, -90, 90);
	s.camera.roll_deg = 0.0;
	s.camera.vfov_deg = uniform(seed, 10, 120);
	if (!gpu_friendly && uniform(seed, 0, 1) < 0.1) {
		s.moon.illuminance_lx = 0.3;
		s.moon.elevation_deg = uniform(seed, -90, 90);
		s.moon.azimuth_deg = uniform(seed, 0, 360);
	}
	if (uniform(seed, 0, 1) < 0.2)
		s.quality.multiscatter_dirs = 64;
	/* From a stream of its own: the atmospheres the seed gave before the
	 * weather keys existed stay the same, the weather comes on top. */
	uint64_t weather_seed = *seed ^ 0x77656174686572ull;
	random_weather(&weather_seed, &s);
	snprintf(s.preset, sizeof(s.preset), "random");
	*ret = s;
}

/* Computing ----------------------------------------------------------------- */

int stab_model(void *ctx, const struct sky_state *s, uint32_t mask, struct model_tables *ret,
	       char *err, size_t err_size)
{
	(void)ctx;
	int rc = model_compute(s, mask, ret);
	if (rc < 0)
		snprintf(err, err_size, "model_compute: %s", strerror(-rc));
	return rc;
}

static double half_to_double(uint16_t h)
{
	int e = (h >> 10) & 0x1f, m = h & 0x3ff;
	double v = e == 0 ? ldexp(m, -24) : e == 31 ? (m ? NAN : INFINITY) : ldexp(m + 1024, e - 25);
	return h & 0x8000 ? -v : v;
}

int stab_engine(void *ctx, const struct sky_state *s, uint32_t mask, struct model_tables *ret,
		char *err, size_t err_size)
{
	struct eng *e = ctx;
	struct eng_timing timing;
	struct model_tables m;
	int rc = eng_compute(e, s, mask, &timing, err, err_size);
	if (rc < 0)
		return rc;
	if (model_tables_new(s, mask, &m) < 0) {
		snprintf(err, err_size, "out of memory");
		return -ENOMEM;
	}
	for (int t = 0; t < STATE_N_TABLES; t++) {
		if (!m.t[t])
			continue;
		size_t n = (size_t)m.w[t] * m.h[t] * m.d[t] * 4;
		const void *src = eng_table(e, (enum state_table)t, NULL);
		/* Half RGB is stored over 2^k (eng.h); A is never scaled. */
		int32_t k = eng_table_scale_log2(e, (enum state_table)t);
		for (size_t i = 0; i < n; i++)
			m.t[t][i] = s->quality.storage == STATE_F16
					    ? ldexp(half_to_double(((const uint16_t *)src)[i]),
						    i % 4 == 3 ? 0 : k)
					    : ((const float *)src)[i];
	}
	*ret = m;
	return 0;
}

/* Invariants ---------------------------------------------------------------- */

void stab_note(struct stab_result *r, enum stab_invariant inv, bool ok, const char *fmt, ...)
{
	r->samples[inv]++;
	if (ok)
		return;
	if (!stab_total_fails(r)) {
		va_list ap;
		va_start(ap, fmt);
		vsnprintf(r->first, sizeof(r->first), fmt, ap);
		va_end(ap);
	}
	r->fails[inv]++;
}

uint64_t stab_total_fails(const struct stab_result *r)
{
	uint64_t n = 0;
	for (int i = 0; i < STAB_N_INVARIANTS; i++)
		n += r->fails[i];
	return n;
}

static double bilinear(const double *tab, uint32_t w, uint32_t h, double u, double v, int ch)
{
	double px = skymap_clamp(u, 0, 1) * w - 0.5, py = skymap_clamp(v, 0, 1) * h - 0.5;
	double fx = px - floor(px), fy = py - floor(py);
	int ix = (int)floor(px), iy = (int)floor(py);
	int x0 = ix < 0 ? 0 : ix, x1 = ix + 1 > (int)w - 1 ? (int)w - 1 : ix + 1;
	int y0 = iy < 0 ? 0 : iy, y1 = iy + 1 > (int)h - 1 ? (int)h - 1 : iy + 1;
	if (x0 > (int)w - 1)
		x0 = (int)w - 1;
	if (y0 > (int)h - 1)
		y0 = (int)h - 1;
	double a = tab[4 * (y0 * w + x0) + ch], b = tab[4 * (y0 * w + x1) + ch];
	double c = tab[4 * (y1 * w + x0) + ch], d = tab[4 * (y1 * w + x1) + ch];
	double top = a + (b - a) * fx, bot = c + (d - c) * fx;
	return top + (bot - top) * fy;
}

/* T to the top at points along rays that stay above the ground must not fall
 * as the point moves towards the top (T(x -> top) = T(x -> y) T(y -> top)).
 * Asserted on the model's own quadrature at 512 steps along the ray (at
 * 64 steps a grazing ray's optical depth wobbles by 5e-4 as the nodes slide
 * past the tangent point); the same
 * points read through the table's bilinear sampler give max_t_ray_drop, a
 * figure of the table's interpolation error, not an invariant. */
static void check_rays(const char *name, const struct sky_state *s, const struct model_tables *m,
		       const struct stab_tol *tol, struct stab_result *r)
{
	static const double alts[] = { 0.0, 1e-3, 0.1, 0.5, 0.9 };
	static const double mus[] = { 1.0, 0.5, 0.1, 0.01, 0.0, -0.05, -0.3 };
	enum { N_MU = sizeof(mus) / sizeof(mus[0]), N_PT = 12 };
	double rb = s->atmo.bottom_radius_km, rt = s->atmo.top_radius_km, shell = rt - rb;
	const double *tab = m->t[STATE_TRANSMITTANCE];

	for (size_t i = 0; i < sizeof(alts) / sizeof(alts[0]); i++)
		for (size_t j = 0; j < N_MU + 1; j++) {
			double h = alts[i] * shell;
			double mu_h = skymap_horizon_cos(rb, h);
			/* The last ray grazes the horizon from just above. */
			double mu = j < N_MU ? mus[j] : mu_h + 1e-7;
			if (mu < mu_h)
				continue;
			double d = skymap_distance_to_top(rb, rt, h, mu), r0 = rb + h;
			double prev_tab[3] = { -1, -1, -1 }, prev_tau[3] = { 0 };
			for (int k = 0; k < N_PT; k++) {
				double t = d * k / N_PT, tau[3], u, v;
				double excess = skymap_rho2(rb, h) + t * (t + 2.0 * r0 * mu);
				double rr = sqrt(rb * rb + fmax(excess, 0.0));
				double hk = excess / (rr + rb), muk = (r0 * mu + t) / rr;
				model_optical_depth(&s->atmo, hk, muk, 512, tau);
				skymap_transmittance_uv(rb, rt, hk, muk, m->w[0], m->h[0], &u, &v);
				for (int ch = 0; ch < 3; ch++) {
					double tr = bilinear(tab, m->w[0], m->h[0], u, v, ch);
					if (k > 0) {
						r->max_t_ray_drop = fmax(r->max_t_ray_drop, prev_tab[ch] - tr);
						stab_note(r, STAB_T_MONOTONE,
						     !(tau[ch] > prev_tau[ch] * (1 + tol->ray_t) + 1e-300),
						     "%s: optical depth grows along a ray from h %g km mu %.9g ch %d point %d: %.9g -> %.9g",
						     name, h, mu, ch, k, prev_tau[ch], tau[ch]);
					}
					prev_tab[ch] = tr;
					prev_tau[ch] = tau[ch];
				}
			}
		}
}

static double table_peak(const struct model_tables *m, int t)
{
	size_t n = (size_t)m->w[t] * m->h[t] * m->d[t] * 4;
	double peak = 0;
	for (size_t i = 0; i < n; i++)
		if (i % 4 != 3 && isfinite(m->t[t][i]))
			peak = fmax(peak, fabs(m->t[t][i]));
	return peak;
}

static void check_symmetry(const char *name, const struct sky_state *s, const struct model_tables *m,
			   const struct stab_tol *tol, struct stab_result *r)
{
	/* Clouds and terrain are no mirror images about the sun's plane: the
	 * symmetry holds for a horizontally uniform atmosphere only. */
	if (s->moon.illuminance_lx > 0 || state_clouds_drawn(s) || s->terrain.path[0])
		return;
	/* A floor of 1e-12 of the sun's illuminance: a ray that grazes the top
	 * of the shell from space enters it on one side and misses it on the
	 * other by a rounding, in tables whose peak is itself ~1e-11. */
	double floor_ = 1e-12 * s->sun.illuminance_lx;
	/* Sky-view: az_i + az_j = 2 az_sun when (i + j + 1) = az_sun W / pi. */
	uint32_t w = m->w[STATE_SKYVIEW], h = m->h[STATE_SKYVIEW];
	double k = s->sun.azimuth_deg * w / 180.0;
	const double *sv = m->t[STATE_SKYVIEW];
	if (sv && fabs(k - nearbyint(k)) < 1e-9) {
		long kk = (long)nearbyint(k);
		double peak = table_peak(m, STATE_SKYVIEW);
		for (uint32_t y = 0; y < h; y++)
			for (uint32_t i = 0; i < w; i++) {
				uint32_t j = (uint32_t)((((kk - 1 - (long)i) % (long)w) + (long)w) % (long)w);
				if (j < i)
					continue;
				for (int ch = 0; ch < 3; ch++) {
					double a = sv[4 * (y * w + i) + ch], b = sv[4 * (y * w + j) + ch];
					double asym = fabs(a - b) <= floor_ ? 0 : peak > 0 ? fabs(a - b) / peak : fabs(a - b);
					r->max_asym = fmax(r->max_asym, asym);
					stab_note(r, STAB_SYMMETRY, asym <= tol->sym_rel,
					     "%s: skyview row %u columns %u/%u ch %d: %.9g vs %.9g", name, y, i, j,
					     ch, a, b);
				}
			}
	}
	/* Aerial: a level camera looking at the sun's azimuth is mirrored left
	 * to right. */
	const double *ap = m->t[STATE_AERIAL];
	double dyaw = fmod(s->camera.yaw_deg - s->sun.azimuth_deg, 360.0);
	if (ap && s->camera.roll_deg == 0.0 && fabs(dyaw) < 1e-12) {
		uint32_t aw = m->w[3], ah = m->h[3], ad = m->d[3];
		double peak = table_peak(m, STATE_AERIAL);
		for (uint32_t z = 0; z < ad; z++)
			for (uint32_t y = 0; y < ah; y++)
				for (uint32_t i = 0; i < aw / 2; i++)
					for (int ch = 0; ch < 3; ch++) {
						double a = ap[4 * ((z * ah + y) * aw + i) + ch];
						double b = ap[4 * ((z * ah + y) * aw + aw - 1 - i) + ch];
						double asym = fabs(a - b) <= floor_ ? 0 : peak > 0 ? fabs(a - b) / peak : fabs(a - b);
						r->max_asym = fmax(r->max_asym, asym);
						stab_note(r, STAB_SYMMETRY, asym <= tol->sym_rel,
						     "%s: aerial slice %u row %u column %u ch %d: %.9g vs %.9g",
						     name, z, y, i, ch, a, b);
					}
	}
}

/* The rows of the transmittance table, as the statement "T does not rise
 * along a ray" implies for them. A ray going up crosses every shell above
 * its point on a shorter path as mu grows, so T(h, mu) grows with mu for
 * mu >= 0, whatever the density. A ray going down is not comparable with
 * its neighbours that way (below an absorbing layer the ray that dips
 * deeper crosses the layer more steeply, on a shorter path: with ozone
 * alone the exact T rises by 0.07 % between such columns), but it comes back
 * up to its altitude with cosine -mu and goes on as that ray:
 * T(h, mu) <= T(h, -mu). T(h, -mu) lies between the two texels of the row
 * around -mu (the row is monotone there), so the larger of the two bounds
 * it without any interpolation error. */
static void check_t_row(const char *name, const struct sky_state *s, const double *x, uint32_t w,
			uint32_t h, uint32_t i, uint32_t y, int ch, const struct stab_tol *tol,
			struct stab_result *r)
{
	double rb = s->atmo.bottom_radius_km, rt = s->atmo.top_radius_km;
	double alt, mu, v = x[4 * ((size_t)y * w + i) + ch];
	double tv = (y + 0.5) / h;

	skymap_transmittance_inverse(rb, rt, (i + 0.5) / w, tv, w, h, &alt, &mu);
	if (mu >= 0.0) {
		if (i == 0)
			return;
		double p = x[4 * ((size_t)y * w + i - 1) + ch];
		stab_note(r, STAB_T_MONOTONE, !(v > p + tol->abs_t),
		     "%s: transmittance row %u rises at column %u ch %d (ray going up): %.9g -> %.9g",
		     name, y, i, ch, p, v);
		return;
	}
	double u_up, v_up;
	skymap_transmittance_uv(rb, rt, alt, -mu, w, h, &u_up, &v_up);
	double c = u_up * w - 0.5;
	uint32_t c0 = c <= 0.0 ? 0 : (uint32_t)c, c1 = c0 + 1 < w ? c0 + 1 : c0;
	double bound = fmax(x[4 * ((size_t)y * w + c0) + ch], x[4 * ((size_t)y * w + c1) + ch]);
	stab_note(r, STAB_T_MONOTONE, !(v > bound + tol->abs_t),
	     "%s: transmittance row %u column %u ch %d (ray going down, mu %.9g) exceeds T at -mu: "
	     "%.9g > %.9g",
	     name, y, i, ch, mu, v, bound);
}

static bool all_zero(const struct atmo *a, bool scattering_only)
{
	for (int i = 0; i < a->n_constituents; i++)
		for (int ch = 0; ch < 3; ch++)
			if (a->c[i].scattering_per_km[ch] != 0 ||
			    (!scattering_only && a->c[i].absorption_per_km[ch] != 0))
				return false;
	return true;
}

void stab_check(const char *name, const struct sky_state *s, const struct model_tables *m,
		const struct stab_tol *tol, struct stab_result *r)
{
	bool no_scattering = all_zero(&s->atmo, true), vacuum = all_zero(&s->atmo, false);

	for (int t = 0; t < STATE_N_TABLES; t++) {
		const double *x = m->t[t];
		if (!x)
			continue;
		uint32_t w = m->w[t], h = m->h[t], d = m->d[t];
		for (uint32_t z = 0; z < d; z++)
			for (uint32_t y = 0; y < h; y++)
				for (uint32_t i = 0; i < w; i++) {
					size_t o = 4 * (((size_t)z * h + y) * w + i);
					for (int ch = 0; ch < 4; ch++) {
						double v = x[o + ch];
						stab_note(r, STAB_FINITE, isfinite(v), "%s: %s texel (%u, %u, %u) ch %d is %g",
						     name, state_table_names[t], i, y, z, ch, v);
						stab_note(r, STAB_NONNEG, !(v < 0), "%s: %s texel (%u, %u, %u) ch %d is %g",
						     name, state_table_names[t], i, y, z, ch, v);
						bool unit = t == STATE_TRANSMITTANCE || ch == 3;
						if (unit)
							stab_note(r, STAB_T_RANGE, !(v > 1.0 + tol->abs_t),
							     "%s: %s texel (%u, %u, %u) ch %d is %.9g > 1", name,
							     state_table_names[t], i, y, z, ch, v);
						else if (t == STATE_MULTISCATTER)
							r->max_psi = fmax(r->max_psi, v);
						else
							r->max_radiance = fmax(r->max_radiance, v);
						if (t == STATE_TRANSMITTANCE && ch < 3)
							check_t_row(name, s, x, w, h, i, y, ch, tol, r);
						if (t == STATE_AERIAL && z > 0) {
							double p = x[o + ch - 4 * (size_t)w * h];
							if (ch == 3)
								stab_note(r, STAB_T_MONOTONE, !(v > p + tol->abs_t),
								     "%s: aerial T rises from slice %u at (%u, %u): %.9g -> %.9g",
								     name, z, i, y, p, v);
							else
								stab_note(r, STAB_L_MONOTONE, !(v < p),
								     "%s: aerial L falls from slice %u at (%u, %u) ch %d: %.9g -> %.9g",
								     name, z, i, y, ch, p, v);
						}
						if (no_scattering && (t == STATE_SKYVIEW || t == STATE_AERIAL) && ch < 3)
							stab_note(r, STAB_VACUUM, v == 0.0, "%s: %s texel (%u, %u, %u) ch %d is %g, not 0",
							     name, state_table_names[t], i, y, z, ch, v);
						if (vacuum && (t == STATE_TRANSMITTANCE || ch == 3) && t != STATE_MULTISCATTER)
							stab_note(r, STAB_VACUUM, v == 1.0, "%s: %s texel (%u, %u, %u) ch %d is %.9g, not 1",
							     name, state_table_names[t], i, y, z, ch, v);
					}
				}
	}
	if (m->t[STATE_TRANSMITTANCE] && tol->ray_t > 0)
		check_rays(name, s, m, tol, r);
	check_symmetry(name, s, m, tol, r);
}

int stab_horizon(const char *name, stab_compute_fn fn, void *ctx, const struct sky_state *s,
		 struct stab_result *r, char *err, size_t err_size)
{
	enum { N = 25 };
	uint32_t w = s->quality.t[STATE_SKYVIEW].width, h = s->quality.t[STATE_SKYVIEW].height;
	double *rows = calloc((size_t)N * h, sizeof(double));
	struct sky_state x = *s;
	int rc = 0;

	if (!rows)
		return -ENOMEM;
	x.moon.illuminance_lx = 0.0;
	for (int k = 0; k < N && rc == 0; k++) {
		struct model_tables m;
		x.sun.elevation_deg = -3.0 + 0.25 * k;
		/* Only the sun moved: the engine keeps transmittance and
		 * multi-scattering from the first computation. */
		rc = fn(ctx, &x, k == 0 ? STATE_ALL_TABLES : STATE_BIT(STATE_SKYVIEW), &m, err, err_size);
		if (rc < 0)
			break;
		for (uint32_t y = 0; y < h; y++) {
			double sum = 0;
			for (uint32_t i = 0; i < w; i++)
				for (int ch = 0; ch < 3; ch++)
					sum += m.t[STATE_SKYVIEW][4 * (y * w + i) + ch];
			rows[(size_t)k * h + y] = sum / w;
		}
		model_tables_finish(&m);
	}
	for (uint32_t y = 0; y < h && rc == 0; y++) {
		double peak = 0, step[N - 1];
		for (int k = 0; k < N; k++)
			peak = fmax(peak, rows[(size_t)k * h + y]);
		for (int k = 0; k + 1 < N; k++)
			step[k] = fabs(rows[(size_t)(k + 1) * h + y] - rows[(size_t)k * h + y]);
		/* The neighbours are the two steps on either side: where the row
		 * has a smooth extremum the step across it is near 0, and at the
		 * ends of the sweep a step next to it has no other neighbour (a thin
		 * atmosphere's peak near sunrise would read as a jump against one
		 * neighbour). A real jump stands out from all four. */
		for (int k = 0; k + 1 < N; k++) {
			double nb = 0;
			for (int d = -2; d <= 2; d++)
				if (d != 0 && k + d >= 0 && k + d + 1 < N)
					nb = fmax(nb, step[k + d]);
			double floor_ = 1e-6 * peak;
			if (step[k] > floor_ && nb > 0)
				r->max_jump_ratio = fmax(r->max_jump_ratio, step[k] / nb);
			stab_note(r, STAB_HORIZON, !(step[k] > 4.0 * nb + floor_) && isfinite(step[k]),
			     "%s: sky-view row %u jumps by %.6g between sun %.2f and %.2f deg (neighbours %.6g)",
			     name, y, step[k], -3.0 + 0.25 * k, -3.0 + 0.25 * (k + 1), nb);
		}
	}
	free(rows);
	return rc;
}

void stab_compare(const struct sky_state *s, const struct model_tables *ref,
		  const struct model_tables *got, double ret_psnr_db[STATE_N_TABLES],
		  double ret_max_rel[STATE_N_TABLES])
{
	(void)s;
	for (int t = 0; t < STATE_N_TABLES; t++) {
		ret_psnr_db[t] = NAN;
		ret_max_rel[t] = NAN;
		if (!ref->t[t] || !got->t[t])
			continue;
		size_t n = (size_t)ref->w[t] * ref->h[t] * ref->d[t] * 4;
		double peak = table_peak(ref, t), se = 0, max_rel = 0;
		for (size_t i = 0; i < n; i++) {
			if (i % 4 == 3)
				continue;
			double a = ref->t[t][i], d = got->t[t][i] - a;
			se += d * d;
			if (fabs(a) > 1e-3 * peak)
				max_rel = fmax(max_rel, fabs(d) / fabs(a));
		}
		double mse = se / (double)(n / 4 * 3);
		ret_psnr_db[t] = mse > 0 ? 10 * log10(peak * peak / mse) : INFINITY;
		ret_max_rel[t] = max_rel;
	}
}
