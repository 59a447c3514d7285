/* bench_stability.c - `skybench stability --markdown FILE`: runs the named
 * stiff cases of truth/stab.c on the model and the engine and writes the
 * invariant results and precision figures as docs/stability.md. */
#include "bench_stability.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/utsname.h>

#include "eng.h"
#include "stab.h"

/* The cells of invariants [first, last]. */
static void inv_cells(FILE *f, const struct stab_result *r, int first, int last)
{
	for (int i = first; i <= last; i++) {
		if (!r->samples[i])
			fprintf(f, " | -");
		else if (!r->fails[i])
			fprintf(f, " | ok (%llu)", (unsigned long long)r->samples[i]);
		else
			fprintf(f, " | **%llu of %llu fail**", (unsigned long long)r->fails[i],
				(unsigned long long)r->samples[i]);
	}
}

/* Non-finite values and the largest relative error of f16 against f32
 * tables, RGB above 1e-3 of each table's peak. */
static void f16_figures(const struct model_tables *a, const struct model_tables *b, size_t *ret_bad,
			double *ret_rel)
{
	double psnr[STATE_N_TABLES], rel[STATE_N_TABLES];
	size_t bad = 0;
	stab_compare(NULL, a, b, psnr, rel);
	*ret_rel = 0;
	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t n = (size_t)b->w[t] * b->h[t] * b->d[t] * 4;
		for (size_t i = 0; i < n; i++)
			bad += !isfinite(b->t[t][i]);
		if (isfinite(rel[t]))
			*ret_rel = fmax(*ret_rel, rel[t]);
	}
	*ret_bad = bad;
}

/* One case of the clouds and terrain on the model side (field, tracer,
 * the model's tables with and without) and on the engine. */
static int cloud_case(struct eng *e, const struct stab_cloud_case *k, struct stab_result *rm,
		      struct stab_result *rg, uint64_t *ret_sum, char *err, size_t n)
{
	struct sky_state s, bound;
	struct model_tables mw, mo, gw, go;
	int rc = stab_cloud_state(k, &s, err, n);

	if (rc < 0 || (rc = stab_cloud_check_model(k->name, &s, rm, ret_sum, err, n)) < 0)
		return rc;
	stab_cloud_bound(&s, &bound);
	if ((rc = stab_model(NULL, &s, STATE_ALL_TABLES, &mw, err, n)) < 0 ||
	    (rc = stab_model(NULL, &bound, STATE_ALL_TABLES, &mo, err, n)) < 0 ||
	    (rc = stab_engine(e, &s, STATE_ALL_TABLES, &gw, err, n)) < 0 ||
	    (rc = stab_engine(e, &bound, STATE_ALL_TABLES, &go, err, n)) < 0)
		return rc;
	stab_check(k->name, &s, &mw, &stab_tol_model, rm);
	stab_check_shadowed(k->name, &mw, &mo, &stab_tol_model, rm);
	stab_check(k->name, &s, &gw, &stab_tol_f32, rg);
	stab_check_shadowed(k->name, &gw, &go, &stab_tol_f32, rg);
	model_tables_finish(&mw);
	model_tables_finish(&mo);
	model_tables_finish(&gw);
	model_tables_finish(&go);
	return 0;
}

/* The clouds' and terrain's cases: invariants and the field's checksum,
 * then each case's keys. */
static int cloud_section(FILE *f, struct eng *e, char *err, size_t n)
{
	fprintf(f, "\n## Clouds and terrain\n\n"
		   "The cases of truth/stab_clouds.c, each against the same state without its clouds "
		   "and terrain. model: the field of proto/skycloud.h and proto/skyterrain.h in double over "
		   "a grid (density finite and within its majorant, the light toward the sun and the "
		   "sky's occlusion in [0, 1]), the air's single scattering with the scene against "
		   "without (shadowed never brighter), the path tracer (finite, >= 0, the same bits on "
		   "one thread and three), the field's checksum computed again in another thread, and "
		   "the model's tables with every invariant; f32: the engine's tables, the same "
		   "invariants. The tables with the scene are held to the same state without it over "
		   "a white ground (stab_cloud_bound): the layers' own light makes the air over a deck "
		   "brighter than over the ground, never more than a white ground would. The model's "
		   "tables hold no cloud term (with and without differ by the ground alone); the "
		   "engine's run these cases (test_stability_gpu). The checksum is the "
		   "field's over the grid (FNV-1a of the doubles' bits): every host gives the same "
		   "(test_stability_clouds holds it).\n\n"
		   "| case | on | stresses | finite | non-negative | in range | shadowed <= unshadowed | "
		   "field the same | field checksum |\n|---|---|---|---|---|---|---|---|---|\n");
	for (size_t c = 0; c < stab_n_cloud_cases; c++) {
		const struct stab_cloud_case *k = &stab_cloud_cases[c];
		struct stab_result rm = { 0 }, rg = { 0 };
		uint64_t sum = 0;
		int rc = cloud_case(e, k, &rm, &rg, &sum, err, n);
		if (rc < 0)
			return rc;
		fprintf(f, "| %s | model | %s", k->name, k->stresses);
		inv_cells(f, &rm, STAB_FINITE, STAB_T_RANGE);
		inv_cells(f, &rm, STAB_SHADOWED, STAB_FIELD_SAME);
		fprintf(f, " | %016llx |\n|  | f32 | ", (unsigned long long)sum);
		inv_cells(f, &rg, STAB_FINITE, STAB_T_RANGE);
		inv_cells(f, &rg, STAB_SHADOWED, STAB_FIELD_SAME);
		fprintf(f, " | |\n");
		fprintf(stderr, "%s done\n", k->name);
	}
	fprintf(f, "\nThe keys of each case, set in order on the defaults (medium sizes); "
		   "`@ridge` and `@cliff` are truth/media.c's synthetic height fields:\n\n"
		   "| case | keys |\n|---|---|\n");
	for (size_t c = 0; c < stab_n_cloud_cases; c++) {
		fprintf(f, "| %s |", stab_cloud_cases[c].name);
		for (int i = 0; i < STAB_CLOUD_KEYS && stab_cloud_cases[c].keys[i]; i++)
			fprintf(f, " `%s`", stab_cloud_cases[c].keys[i]);
		if (stab_cloud_cases[c].utc_s > 0)
			fprintf(f, ", the field placed at %.0f s (POSIX)", stab_cloud_cases[c].utc_s);
		fprintf(f, " |\n");
	}
	return 0;
}

/* The title, the device and sizes, and the invariants table's head. */
static void write_header(FILE *f, struct eng *e)
{
	struct sky_state q;
	state_default(&q);
	stab_medium(&q);
	fprintf(f, "# Numerical stability on stiff and extreme atmospheres\n\n"
		   "Generated by `build/tools/skybench stability --markdown docs/stability.md` "
		   "(tools/bench_stability.c, cases and invariants in truth/stab.c); do not edit by hand.\n"
		   "Device: %s. Sizes: transmittance %ux%u/%u steps, multiscatter %ux%u/%u steps x %u dirs, "
		   "sky-view %ux%u/%u steps, aerial %ux%ux%u/%u steps.\n\n",
		   eng_device(e)->name, q.quality.t[0].width, q.quality.t[0].height, q.quality.t[0].steps,
		   q.quality.t[1].width, q.quality.t[1].height, q.quality.t[1].steps, q.quality.multiscatter_dirs,
		   q.quality.t[2].width, q.quality.t[2].height, q.quality.t[2].steps, q.quality.t[3].width,
		   q.quality.t[3].height, q.quality.t[3].depth, q.quality.t[3].steps);
	fprintf(f, "Invariants: the number of values checked, or how many failed. Precision: the float32 "
		   "engine against the float64 model (daemon/model.c) at the same sizes and step counts, "
		   "so the difference is precision alone; PSNR with the model's largest RGB as peak, "
		   "max rel among RGB above 1e-3 of it. f16: the same engine with storage=f16 against its "
		   "float32 tables. The random sweeps (10,000 atmospheres on the model, 300 on the engine) "
		   "are in tests/numerical/test_stability_model.c and "
		   "tests/numerical/test_stability_gpu.c.\n\n");

	fprintf(f, "## Invariants\n\n| case | on | stresses");
	for (int i = 0; i <= STAB_SYMMETRY; i++)
		fprintf(f, " | %s", stab_invariant_names[i]);
	fprintf(f, " | horizon (model) | psi max | T drop along ray (table) |\n|---|---|---");
	for (int i = 0; i <= STAB_SYMMETRY + 3; i++)
		fprintf(f, "|---");
	fprintf(f, "|\n");
}

int bench_stability(int argc, char **argv)
{
	const char *path = NULL;
	char err[512];
	for (int i = 0; i < argc; i++)
		if (!strcmp(argv[i], "--markdown") && i + 1 < argc)
			path = argv[++i];
	if (!path) {
		fprintf(stderr, "usage: skybench stability --markdown FILE\n");
		return 2;
	}
	struct eng *e;
	if (eng_new(NULL, err, sizeof(err), &e) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		return 1;
	}
	FILE *f = fopen(path, "we");
	if (!f) {
		perror(path);
		eng_free(e);
		return 1;
	}
	write_header(f, e);

	FILE *prec = tmpfile();
	fprintf(prec, "## Precision (float32 engine vs float64 model) and float16 storage\n\n"
		      "| case | transmittance dB / max rel | multiscatter | sky-view | aerial | f16 non-finite | f16 max rel |\n"
		      "|---|---|---|---|---|---|---|\n");
	int rc = 0;
	for (size_t c = 0; c < stab_n_cases && rc == 0; c++) {
		struct sky_state s;
		struct model_tables ref, gpu, half;
		struct stab_result rm = { 0 }, rg = { 0 };
		const char *name = stab_cases[c].name;
		state_default(&s);
		stab_cases[c].fill(&s);
		stab_medium(&s);
		if ((rc = stab_model(NULL, &s, STATE_ALL_TABLES, &ref, err, sizeof(err))) < 0 ||
		    (rc = stab_engine(e, &s, STATE_ALL_TABLES, &gpu, err, sizeof(err))) < 0)
			break;
		stab_check(name, &s, &ref, &stab_tol_model, &rm);
		stab_check(name, &s, &gpu, &stab_tol_f32, &rg);
		struct sky_state hz = s;
		stab_small(&hz);
		hz.quality.t[STATE_SKYVIEW] = s.quality.t[STATE_SKYVIEW];
		if ((rc = stab_horizon(name, stab_model, NULL, &hz, &rm, err, sizeof(err))) < 0)
			break;
		for (int pass = 0; pass < 2; pass++) {
			const struct stab_result *r = pass ? &rg : &rm;
			fprintf(f, "| %s | %s | %s", pass ? "" : name, pass ? "f32" : "model", pass ? "" : stab_cases[c].stresses);
			inv_cells(f, r, 0, STAB_SYMMETRY);
			if (pass)
				fprintf(f, " | | %.3g | %.2g |\n", r->max_psi, r->max_t_ray_drop);
			else if (r->fails[STAB_HORIZON])
				fprintf(f, " | **%llu of %llu fail** (ratio %.1f) | %.3g | %.2g |\n",
					(unsigned long long)r->fails[STAB_HORIZON],
					(unsigned long long)r->samples[STAB_HORIZON], r->max_jump_ratio, r->max_psi,
					r->max_t_ray_drop);
			else
				fprintf(f, " | ok (ratio %.2f) | %.3g | %.2g |\n", r->max_jump_ratio, r->max_psi,
					r->max_t_ray_drop);
		}
		double psnr[STATE_N_TABLES], rel[STATE_N_TABLES], f16_rel;
		size_t f16_bad;
		stab_compare(&s, &ref, &gpu, psnr, rel);
		s.quality.storage = STATE_F16;
		if ((rc = stab_engine(e, &s, STATE_ALL_TABLES, &half, err, sizeof(err))) < 0)
			break;
		f16_figures(&gpu, &half, &f16_bad, &f16_rel);
		fprintf(prec, "| %s", name);
		for (int t = 0; t < STATE_N_TABLES; t++)
			fprintf(prec, " | %.1f / %.1e", psnr[t], rel[t]);
		fprintf(prec, " | %zu | %.1e |\n", f16_bad, f16_rel);
		model_tables_finish(&ref);
		model_tables_finish(&gpu);
		model_tables_finish(&half);
		fprintf(stderr, "%s done\n", name);
	}
	if (rc < 0)
		fprintf(stderr, "skybench: %s\n", err);
	rewind(prec);
	fputc('\n', f);
	for (int ch; (ch = fgetc(prec)) != EOF;)
		fputc(ch, f);
	fclose(prec);
	if (rc == 0 && (rc = cloud_section(f, e, err, sizeof(err))) < 0)
		fprintf(stderr, "skybench: %s\n", err);
	fprintf(f, "\n## Multi-scattering as f_ms -> 1\n\n"
		   "The engine neither clamps f_ms nor sums a series: it computes 1 - f_ms directly as what "
		   "leaves each ray (transmittance to its end) plus what is absorbed along it, a sum of "
		   "non-negative terms that telescopes to exactly 1 - f_ms, so psi_ms = L2 / (1 - f_ms) never "
		   "divides by a cancelled difference. A floor of 1e-6 on 1 - f_ms only keeps 0/0 away where "
		   "nothing escapes (then L2 is 0 too). The column psi max above is the largest psi_ms per unit "
		   "illuminance; the largest in the 10,000-atmosphere sweep is printed by test_stability_model.\n");
	fclose(f);
	eng_free(e);
	return rc < 0 ? 1 : 0;
}
