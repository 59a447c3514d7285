/* skytruth.c - the ground truth on the command line: sky radiance and its
 * standard error per view direction from the path tracer, for the sky state
 * that the same key=value pairs give skyd.
 *
 *   skytruth [key=value ...] [--error 0.01] [--threads N] [--seed S]
 *            [--dirs elevation:azimuth,...] [--mode sky|single|ground]
 *            [--min-samples N] [--max-samples N] [--batch N] [--reference]
 *            [--isotropic] [--delta-m CONSTITUENT] [--delta-excess] [--delta-f F]
 *            [--tables] [--model FACTOR] [--sos] [--view air|all]
 *
 * --tables adds the engine's sky radiance per direction (the sky-view table
 * computed by the default Vulkan device for the same state, read as libsky
 * reads it); --model FACTOR the double-precision model's (truth/model.c) at
 * the state's table sizes with every step count times FACTOR. Both come
 * after the truth's columns, to separate the technique (the model) from its
 * discretisation on the GPU (the tables) at the horizon and in colour.
 * --sos adds truth/sos.c's plane-parallel answer, scalar then polarized, for
 * the state's Rayleigh constituents alone (their vertical optical depth per
 * channel; the others, the curvature and the ground's albedo are left out)
 * seen from the ground, for views above the horizon with the sun up.
 *
 * A direction of --dirs is elevation:azimuth, or tTANGENT_KM:azimuth for
 * the view down that grazes the air at that altitude (the limb, as seen
 * from altitude_km above it, inside the air or above it: the tracer starts
 * such rays where they enter the air).
 *
 * --isotropic and --delta-m trace the sky tables' assumptions (pt_approx):
 * light scattered once already scatters isotropically; the constituent's
 * phase delta-M scaled for the orders >= 2 (f its second Legendre moment,
 * g' = (g1 - f) / (1 - f); --delta-f sets another f); --delta-excess keeps the light scattered once
 * after the forward peak, which the TMS correction drops.
 *
 * The state's cloud layers and terrain (cloudN_*, terrain=...) are traced
 * as media (docs/truth.md, "Clouds and terrain"): --view air (the default)
 * is the sky tables' view ray, the air's light through them; --view all
 * what an eye sees, the clouds and the terrain on the view ray too.
 * --reference then shades the single scattering by them.
 *
 * The sun of the state lights the sky (sun_illuminance_lx times sun_color per
 * channel); the moon is not traced. Radiance is printed in cd/m2 per
 * channel when the illuminance is in lx.
 */
#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "eng.h"
#include "media.h"
#include "model.h"
#include "proto.h"
#include "pt.h"
#include "skysample.h"
#include "sos.h"
#include "state.h"

#define MAX_DIRS 4096

/* The tangent altitude of each direction given as tH:AZ, NaN for the
 * others; resolve_tangents turns them into elevations. */
static double tangent_km[MAX_DIRS];

static const char default_dirs[] = "90:0,60:180,30:180,30:0,10:90,2:180,2:0,-5:180";

static void usage(FILE *f)
{
	fprintf(f,
		"usage: skytruth [key=value ...] [--error REL] [--threads N] [--seed S]\n"
		"                [--dirs EL:AZ,...] [--mode sky|single|ground]\n"
		"                [--min-samples N] [--max-samples N] [--batch N] [--reference]\n"
		"                [--isotropic] [--delta-m CONSTITUENT] [--delta-excess] [--delta-f F]\n"
		"                [--tables] [--model FACTOR] [--sos] [--view air|all]\n"
		"keys are skyd's state keys (preset, altitude_km, sun_elevation_deg, ...);\n"
		"terrain=@ridge and terrain=@cliff are truth/media.h's synthetic fields.\n"
		"--dirs EL:AZ in degrees, or tKM:AZ: the view down that grazes the air at\n"
		"KM of altitude (the limb; KM below altitude_km).\n"
		"default --dirs %s\n", default_dirs);
}

static int parse_u64(const char *s, uint64_t *ret)
{
	char *end;
	if (!*s || *s == '-' || *s == '+')
		return -EINVAL;
	errno = 0;
	unsigned long long u = strtoull(s, &end, 10);
	if (*end || errno)
		return -EINVAL;
	*ret = u;
	return 0;
}

static int parse_dirs(const char *list, struct pt_dir *dirs, size_t *ret_n)
{
	char buf[65536];
	size_t n = 0;
	if (strlen(list) >= sizeof(buf))
		return -EINVAL;
	snprintf(buf, sizeof(buf), "%s", list);
	for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok;
	     tok = strtok_r(NULL, ",", &save)) {
		char *colon = strchr(tok, ':');
		if (!colon || n == MAX_DIRS)
			return -EINVAL;
		*colon = 0;
		tangent_km[n] = NAN;
		dirs[n].elevation_deg = 0.0;	/* for tH: resolve_tangents sets it */
		if (tok[0] == 't' ? proto_parse_number(tok + 1, &tangent_km[n]) < 0 || !(tangent_km[n] >= 0.0)
				  : proto_parse_number(tok, &dirs[n].elevation_deg) < 0 ||
				    fabs(dirs[n].elevation_deg) > 90.0)
			return -EINVAL;
		if (proto_parse_number(colon + 1, &dirs[n].azimuth_deg) < 0)
			return -EINVAL;
		n++;
	}
	if (!n)
		return -EINVAL;
	*ret_n = n;
	return 0;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The command line's settings. */
struct args {
	struct sky_state s;
	struct pt_options opt;
	size_t n;		/* directions */
	int reference;
	struct pt_approx ap;
	uint64_t delta_m;	/* 1 + --delta-m's constituent, 0 none */
	double delta_f;		/* --delta-f, < 0 for the phase's own */
	int tables;		/* --tables */
	uint64_t model_factor;	/* --model, 0 none */
	int sos;		/* --sos */
	enum pt_view view;	/* --view */
};

/* Sets option a from its value v. Returns 0, -EINVAL for a bad value, or
 * -ENOENT for an option that does not exist. */
static int set_option(struct args *g, struct pt_dir *dirs, const char *a, const char *v)
{
	struct pt_options *opt = &g->opt;
	uint64_t u;
	double d;
	int bad = 0;
	if (strcmp(a, "--error") == 0)
		bad = proto_parse_number(v, &d) < 0 || d < 0.0 || (opt->rel_error = d, 0);
	else if (strcmp(a, "--threads") == 0)
		bad = parse_u64(v, &u) < 0 || u > 256 || (opt->threads = (int)u, 0);
	else if (strcmp(a, "--seed") == 0)
		bad = parse_u64(v, &u) < 0 || (opt->seed = u, 0);
	else if (strcmp(a, "--min-samples") == 0)
		bad = parse_u64(v, &u) < 0 || (opt->min_samples = u, 0);
	else if (strcmp(a, "--max-samples") == 0)
		bad = parse_u64(v, &u) < 0 || !u || (opt->max_samples = u, 0);
	else if (strcmp(a, "--batch") == 0)
		bad = parse_u64(v, &u) < 0 || !u || u > (1u << 30) || (opt->batch = (uint32_t)u, 0);
	else if (strcmp(a, "--delta-m") == 0)
		bad = parse_u64(v, &u) < 0 || u >= ATMO_MAX_CONSTITUENTS || (g->delta_m = u + 1, 0);
	else if (strcmp(a, "--delta-f") == 0)
		bad = proto_parse_number(v, &d) < 0 || !(d >= 0.0 && d < 1.0) || (g->delta_f = d, 0);
	else if (strcmp(a, "--model") == 0)
		bad = parse_u64(v, &u) < 0 || !u || u > 64 || (g->model_factor = u, 0);
	else if (strcmp(a, "--dirs") == 0)
		bad = parse_dirs(v, dirs, &g->n) < 0;
	else if (strcmp(a, "--view") == 0)
		bad = strcmp(v, "air") == 0 ? (g->view = PT_VIEW_AIR, 0)
		      : strcmp(v, "all") == 0 ? (g->view = PT_VIEW_ALL, 0) : 1;
	else if (strcmp(a, "--mode") == 0) {
		if (strcmp(v, "sky") == 0)
			opt->mode = PT_SKY;
		else if (strcmp(v, "single") == 0)
			opt->mode = PT_SINGLE;
		else if (strcmp(v, "ground") == 0)
			opt->mode = PT_GROUND;
		else
			bad = 1;
	} else {
		return -ENOENT;
	}
	return bad ? -EINVAL : 0;
}

/* --delta-m's approximation: f (the phase's second Legendre moment unless
 * --delta-f) and g'. Returns 0, or 2 for a constituent the state lacks. */
static int set_delta_m(struct args *g)
{
	if (!g->delta_m)
		return 0;
	const struct atmo_constituent *c = &g->s.atmo.c[g->delta_m - 1];
	if ((int)g->delta_m > g->s.atmo.n_constituents) {
		fprintf(stderr, "skytruth: --delta-m: no constituent %d\n", (int)g->delta_m - 1);
		return 2;
	}
	g->ap.delta_m = (int)g->delta_m;
	g->ap.delta_f = g->delta_f >= 0.0 ? g->delta_f : phase_legendre(c->phase, c->g, 2);
	g->ap.delta_g = (phase_legendre(c->phase, c->g, 1) - g->ap.delta_f) / (1.0 - g->ap.delta_f);
	return 0;
}

/* Parses the command line into g and dirs. Returns -1 to go on, or the
 * exit status: 0 after --help, 1 or 2 on an error (said on stderr). */
static int parse_args(int argc, char **argv, struct args *g, struct pt_dir *dirs)
{
	char err[256];

	state_default(&g->s);
	pt_options_default(&g->opt);
	if (parse_dirs(default_dirs, dirs, &g->n) < 0)
		return 1;
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
		if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
			usage(stdout);
			return 0;
		} else if (strcmp(a, "--reference") == 0) {
			g->reference = 1;
		} else if (strcmp(a, "--isotropic") == 0) {
			g->ap.isotropic = 1;
		} else if (strcmp(a, "--tables") == 0) {
			g->tables = 1;
		} else if (strcmp(a, "--sos") == 0) {
			g->sos = 1;
		} else if (strcmp(a, "--delta-excess") == 0) {
			g->ap.delta_excess = 1;
		} else if (strncmp(a, "--", 2) == 0) {
			if (!v) {
				fprintf(stderr, "skytruth: %s needs a value\n", a);
				return 2;
			}
			i++;
			int rc = set_option(g, dirs, a, v);
			if (rc == -ENOENT) {
				fprintf(stderr, "skytruth: unknown option %s\n", a);
				usage(stderr);
				return 2;
			}
			if (rc < 0) {
				fprintf(stderr, "skytruth: %s: bad value '%s'\n", a, v);
				return 2;
			}
		} else {
			char kv[512];
			const char *k = media_expand_key(a, kv, sizeof(kv));
			if (!k) {
				fprintf(stderr, "skytruth: %s: %s\n", a, strerror(errno));
				return 2;
			}
			if (state_set_pair(&g->s, k, NULL, err, sizeof(err)) < 0) {
				fprintf(stderr, "skytruth: %s\n", err);
				return 2;
			}
		}
	}
	if (state_validate(&g->s, 0, err, sizeof(err)) < 0) {
		fprintf(stderr, "skytruth: %s\n", err);
		return 2;
	}
	return set_delta_m(g) ? 2 : -1;
}

/* The sky radiance of a sky-view table of s's size in texels (RGBA float32),
 * read as libsky reads it, in n directions. */
static void sample_sky(const struct sky_state *s, const void *texels, int32_t scale_log2,
		       uint32_t format, const struct pt_dir *dirs, size_t n, double (*ret)[3])
{
	struct skysample_table t = { .texels = texels, .format = format,
		.width = s->quality.t[STATE_SKYVIEW].width,
		.height = s->quality.t[STATE_SKYVIEW].height, .depth = 1,
		.rgb_scale_log2 = scale_log2 };
	struct sky_shm_state st = { .altitude_km = s->altitude_km,
		.bottom_radius_km = s->atmo.bottom_radius_km,
		.top_radius_km = s->atmo.top_radius_km };
	for (size_t i = 0; i < n; i++)
		skysample_sky(&t, &st, dirs[i].elevation_deg * M_PI / 180.0,
			      dirs[i].azimuth_deg * M_PI / 180.0, ret[i]);
}

/* --tables: the engine's sky-view table for s in n directions. Returns 0,
 * or 77 without a Vulkan device, 1 on a device error (said on stderr). */
static int engine_sky(const struct sky_state *s, const struct pt_dir *dirs, size_t n,
		      double (*ret)[3])
{
	char err[512];
	struct eng *e;
	struct eng_timing t;
	if (eng_new(NULL, err, sizeof(err), &e) < 0) {
		fprintf(stderr, "skytruth: %s\n", err);
		return 77;
	}
	const uint32_t mask = STATE_BIT(STATE_TRANSMITTANCE) | STATE_BIT(STATE_MULTISCATTER) |
			      STATE_BIT(STATE_SKYVIEW);
	if (eng_compute(e, s, mask, &t, err, sizeof(err)) < 0) {
		fprintf(stderr, "skytruth: %s\n", err);
		eng_free(e);
		return 1;
	}
	sample_sky(s, eng_table(e, STATE_SKYVIEW, NULL), eng_table_scale_log2(e, STATE_SKYVIEW),
		   s->quality.storage == STATE_F16 ? SKY_FORMAT_RGBA16F : SKY_FORMAT_RGBA32F,
		   dirs, n, ret);
	eng_free(e);
	return 0;
}

/* --model: the double-precision model's sky-view table for s with every
 * step count times factor, in n directions. Returns 0 or 1 (said). */
static int model_sky(const struct sky_state *s, uint64_t factor, const struct pt_dir *dirs,
		     size_t n, double (*ret)[3])
{
	struct sky_state r;
	struct model_tables m;
	model_refine(s, (uint32_t)factor, &r);
	if (model_compute(&r, STATE_BIT(STATE_SKYVIEW), &m) < 0) {
		fprintf(stderr, "skytruth: the model: out of memory\n");
		return 1;
	}
	size_t texels = (size_t)m.w[STATE_SKYVIEW] * m.h[STATE_SKYVIEW];
	float *f = malloc(4 * texels * sizeof(*f));
	if (!f) {
		model_tables_finish(&m);
		return 1;
	}
	for (size_t i = 0; i < 4 * texels; i++)
		f[i] = (float)m.t[STATE_SKYVIEW][i];
	sample_sky(&r, f, 0, SKY_FORMAT_RGBA32F, dirs, n, ret);
	free(f);
	model_tables_finish(&m);
	return 0;
}

/* --sos: truth/sos.c for the state's Rayleigh column, scalar (ret[i][0..2])
 * and polarized (ret[i][3..5]), the sun's illuminance per channel. Views
 * at or below the horizon, or the sun not above it, give NAN. Returns 0 or
 * 1 (said on stderr). */
static int sos_sky(const struct sky_state *s, const struct pt_dir *dirs, size_t n,
		   double (*ret)[6])
{
	struct atmo a = s->atmo;
	for (int i = 0; i < a.n_constituents; i++)
		if (a.c[i].phase != ATMO_PHASE_RAYLEIGH)
			for (int ch = 0; ch < 3; ch++)
				a.c[i].scattering_per_km[ch] = a.c[i].absorption_per_km[ch] = 0.0;
	double tau[3], out[MAX_DIRS];
	struct sos_view v[MAX_DIRS];
	size_t m = 0;
	atmo_vertical_optical_depth(&a, 100000, tau);
	for (size_t i = 0; i < n; i++) {
		for (int k = 0; k < 6; k++)
			ret[i][k] = NAN;
		if (dirs[i].elevation_deg > 0.0)
			v[m++] = (struct sos_view){ dirs[i].elevation_deg,
						    dirs[i].azimuth_deg - s->sun.azimuth_deg };
	}
	if (!m || !(s->sun.elevation_deg > 0.0))
		return 0;
	for (int pol = 0; pol < 2; pol++)
		for (int ch = 0; ch < 3; ch++) {
			struct sos_layer l = { .tau = tau[ch], .sun_elevation_deg = s->sun.elevation_deg,
					       .irradiance = s->sun.illuminance_lx * s->sun.color[ch],
					       .polarized = pol };
			if (!(tau[ch] > 0.0) || sos_rayleigh(&l, v, m, out, NULL) < 0) {
				fprintf(stderr, "skytruth: --sos: no Rayleigh column to solve\n");
				return 1;
			}
			for (size_t i = 0, j = 0; i < n; i++)
				if (dirs[i].elevation_deg > 0.0)
					ret[i][3 * pol + ch] = out[j++];
		}
	return 0;
}

/* Traces g's directions and prints one line each, between a header and
 * the time taken. Returns the exit status. */
static int trace(const struct args *g, const struct pt_dir *dirs, struct pt_result *res,
		 double (*tab)[3], double (*mod)[3], double (*sos)[6])
{
	const struct sky_state *s = &g->s;
	const struct pt_approx *ap = &g->ap;
	struct pt_sun sun = { .elevation_deg = s->sun.elevation_deg,
		.azimuth_deg = s->sun.azimuth_deg,
		.angular_radius_deg = s->sun.angular_radius_deg };
	for (int ch = 0; ch < 3; ch++)
		sun.illuminance[ch] = s->sun.illuminance_lx * s->sun.color[ch];

	static const char *const modes[] = { "sky", "single", "ground" };
	printf("# skytruth: preset %s altitude_km %.9g sun_elevation_deg %.9g "
	       "sun_azimuth_deg %.9g illuminance %.9g,%.9g,%.9g mode %s error %g seed %llu"
	       " isotropic %d delta_m %d f %.6g g' %.6g\n",
	       s->preset, s->altitude_km, sun.elevation_deg, sun.azimuth_deg,
	       sun.illuminance[0], sun.illuminance[1], sun.illuminance[2], modes[g->opt.mode],
	       g->opt.rel_error, (unsigned long long)g->opt.seed, ap->isotropic, ap->delta_m - 1,
	       ap->delta_f, ap->delta_g);
	fflush(stdout);

	struct media md;
	char err[256];
	if (media_from_state(s, &md, err, sizeof(err)) < 0) {
		fprintf(stderr, "skytruth: %s\n", err);
		return 1;
	}
	md.scene.view = g->view;
	if (media_present(s))
		printf("# clouds: %d layers drawn; terrain: %s; view: %s\n", md.scene.n_layers,
		       md.scene.terrain ? s->terrain.path : "none", g->view == PT_VIEW_ALL ? "all" : "air");
	double t0 = now_s();
	int r = ap->isotropic || ap->delta_m ?
		(media_present(s) ? -ENOTSUP :
		 pt_render_approx(&s->atmo, s->altitude_km, &sun, dirs, g->n, &g->opt, ap, res)) :
		pt_render_scene(&s->atmo, s->altitude_km, &sun, &md.scene, dirs, g->n, &g->opt, res);
	double elapsed = now_s() - t0;
	if (r < 0) {
		fprintf(stderr, "skytruth: path tracing failed: %s%s\n", strerror(-r),
			r == -ENOTSUP ? " (--isotropic and --delta-m trace a clear sky only)" : "");
		media_finish(&md);
		return 1;
	}

	uint64_t total = 0;
	printf("# elevation_deg azimuth_deg L_r L_g L_b se_r se_g se_b samples%s%s%s%s\n",
	       g->reference ? " ref_r ref_g ref_b" : "", g->tables ? " tab_r tab_g tab_b" : "",
	       g->model_factor ? " model_r model_g model_b" : "",
	       g->sos ? " sos_r sos_g sos_b pol_r pol_g pol_b" : "");
	for (size_t i = 0; i < g->n; i++) {
		printf("%.6g %.6g %.9g %.9g %.9g %.3g %.3g %.3g %llu", dirs[i].elevation_deg,
		       dirs[i].azimuth_deg, res[i].radiance[0], res[i].radiance[1],
		       res[i].radiance[2], res[i].std_error[0], res[i].std_error[1],
		       res[i].std_error[2], (unsigned long long)res[i].samples);
		if (g->reference) {
			double ref[3];
			pt_single_scatter_scene(&s->atmo, s->altitude_km, &sun, &md.scene, &dirs[i], ref);
			printf(" %.9g %.9g %.9g", ref[0], ref[1], ref[2]);
		}
		if (g->tables)
			printf(" %.9g %.9g %.9g", tab[i][0], tab[i][1], tab[i][2]);
		if (g->model_factor)
			printf(" %.9g %.9g %.9g", mod[i][0], mod[i][1], mod[i][2]);
		for (int k = 0; g->sos && k < 6; k++)
			printf(" %.9g", sos[i][k]);
		printf("\n");
		total += res[i].samples;
	}
	printf("# time_s %.3f paths %llu (x3 channels) paths_per_s %.0f\n", elapsed,
	       (unsigned long long)total, elapsed > 0 ? 3.0 * (double)total / elapsed : 0.0);
	media_finish(&md);
	return 0;
}

/* Turns the tangent altitudes of --dirs into elevations below the
 * horizontal of the observer of g. Returns 0, or 2 for a tangent altitude
 * at or above the observer's (said on stderr). */
static int resolve_tangents(const struct args *g, struct pt_dir *dirs)
{
	double rb = g->s.atmo.bottom_radius_km, h = g->s.altitude_km > 0.0 ? g->s.altitude_km : 0.0;
	for (size_t i = 0; i < g->n; i++) {
		if (isnan(tangent_km[i]))
			continue;
		if (!(tangent_km[i] < h)) {
			fprintf(stderr, "skytruth: --dirs t%g: the tangent altitude must be below altitude_km %g\n",
				tangent_km[i], h);
			return 2;
		}
		dirs[i].elevation_deg = -acos((rb + tangent_km[i]) / (rb + h)) * 180.0 / M_PI;
	}
	return 0;
}

int main(int argc, char **argv)
{
	static struct pt_dir dirs[MAX_DIRS];
	static struct pt_result res[MAX_DIRS];
	static double tab[MAX_DIRS][3], mod[MAX_DIRS][3], sos[MAX_DIRS][6];
	struct args g = { .delta_f = -1.0 };

	int status = parse_args(argc, argv, &g, dirs);
	if (status >= 0)
		return status;
	if (resolve_tangents(&g, dirs))
		return 2;
	if (g.tables && (status = engine_sky(&g.s, dirs, g.n, tab)) != 0)
		return status;
	if (g.model_factor && (status = model_sky(&g.s, g.model_factor, dirs, g.n, mod)) != 0)
		return status;
	if (g.sos && (status = sos_sky(&g.s, dirs, g.n, sos)) != 0)
		return status;
	return trace(&g, dirs, res, tab, mod, sos);
}
