/* test_params.c - the shaders and the engine agree on what they share: read
 * from the embedded SPIR-V, every specialization constant's id, every
 * descriptor's binding, the uniform block's layout and the aerial job's
 * match sky_params.h as the C compiler sees it (struct gpu_params, struct
 * gpu_aerial_job, SPEC_*, BINDING_*). */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "shaders.h"
#include "sky_params.h"
#include "test.h"

/* SPIR-V opcodes and decorations read here (SPIR-V 1.3 specification). */
enum {
	OP_NAME = 5, OP_MEMBER_NAME = 6, OP_TYPE_INT = 21, OP_TYPE_FLOAT = 22,
	OP_TYPE_VECTOR = 23, OP_TYPE_ARRAY = 28, OP_TYPE_RUNTIME_ARRAY = 29, OP_TYPE_STRUCT = 30,
	OP_TYPE_POINTER = 32, OP_CONSTANT = 43,
	OP_SPEC_CONSTANT_TRUE = 48, OP_SPEC_CONSTANT_FALSE = 49, OP_SPEC_CONSTANT = 50,
	OP_VARIABLE = 59, OP_DECORATE = 71, OP_MEMBER_DECORATE = 72,
	DEC_SPEC_ID = 1, DEC_ARRAY_STRIDE = 6, DEC_BINDING = 33, DEC_OFFSET = 35,
};

#define MAX_MEMBERS 32

/* What this test needs of one id of a module. */
struct spv_id {
	const char *name;
	const uint32_t *def;		/* the instruction that defines it, if a type, constant or variable */
	int spec_id, binding, array_stride;
	const char *member_name[MAX_MEMBERS];
	int member_offset[MAX_MEMBERS];
};

struct spv {
	const char *shader;
	uint32_t bound;
	struct spv_id *ids;
};

static void record(struct spv *m, const uint32_t *ins, uint32_t words)
{
	uint32_t op = ins[0] & 0xffff;
	if (op == OP_NAME && ins[1] < m->bound)
		m->ids[ins[1]].name = (const char *)&ins[2];
	else if (op == OP_MEMBER_NAME && ins[1] < m->bound && ins[2] < MAX_MEMBERS)
		m->ids[ins[1]].member_name[ins[2]] = (const char *)&ins[3];
	else if (op == OP_DECORATE && words >= 4 && ins[1] < m->bound) {
		struct spv_id *id = &m->ids[ins[1]];
		if (ins[2] == DEC_SPEC_ID)
			id->spec_id = (int)ins[3];
		else if (ins[2] == DEC_BINDING)
			id->binding = (int)ins[3];
		else if (ins[2] == DEC_ARRAY_STRIDE)
			id->array_stride = (int)ins[3];
	} else if (op == OP_MEMBER_DECORATE && words >= 5 && ins[1] < m->bound && ins[2] < MAX_MEMBERS &&
		   ins[3] == DEC_OFFSET) {
		m->ids[ins[1]].member_offset[ins[2]] = (int)ins[4];
	} else if ((op == OP_TYPE_INT || op == OP_TYPE_FLOAT || op == OP_TYPE_VECTOR ||
		    op == OP_TYPE_ARRAY || op == OP_TYPE_RUNTIME_ARRAY || op == OP_TYPE_STRUCT ||
		    op == OP_TYPE_POINTER) && ins[1] < m->bound) {
		m->ids[ins[1]].def = ins;
	} else if ((op == OP_CONSTANT || op == OP_SPEC_CONSTANT || op == OP_SPEC_CONSTANT_TRUE ||
		    op == OP_SPEC_CONSTANT_FALSE || op == OP_VARIABLE) && ins[2] < m->bound) {
		m->ids[ins[2]].def = ins;
	}
}

/* Indexes the module of one embedded shader; 0 or -1 if it is not SPIR-V. */
static int spv_load(const struct shader_code *code, struct spv *ret)
{
	const uint32_t *w = code->words;
	size_t n = code->bytes / 4;

	memset(ret, 0, sizeof(*ret));
	ret->shader = code->name;
	if (n < 5 || w[0] != 0x07230203)
		return -1;
	ret->bound = w[3];
	ret->ids = calloc(ret->bound, sizeof(*ret->ids));
	if (!ret->ids)
		return -1;
	for (uint32_t i = 0; i < ret->bound; i++) {
		ret->ids[i].spec_id = -1;
		ret->ids[i].binding = -1;
		for (int k = 0; k < MAX_MEMBERS; k++)
			ret->ids[i].member_offset[k] = -1;
	}
	for (size_t i = 5; i < n;) {
		uint32_t words = w[i] >> 16;
		if (words == 0 || i + words > n)
			return -1;
		record(ret, &w[i], words);
		i += words;
	}
	return 0;
}

static const char *id_name(const struct spv *m, uint32_t id)
{
	return id < m->bound && m->ids[id].name ? m->ids[id].name : "";
}

static const uint32_t *id_def(const struct spv *m, uint32_t id)
{
	return id < m->bound ? m->ids[id].def : NULL;
}

/* The size in bytes of a member of type id, as laid out in the block
 * (32-bit floats and uints, vec3 and vec4 of float32, arrays by their
 * stride, structs to their last member's end); -1 for anything else,
 * which the blocks must not hold. */
static long type_size(const struct spv *m, uint32_t id)
{
	const uint32_t *d = id_def(m, id);
	if (!d)
		return -1;
	switch (d[0] & 0xffff) {
	case OP_TYPE_FLOAT:
		return d[2] == 32 ? 4 : -1;
	case OP_TYPE_INT:
		return d[2] == 32 && d[3] == 0 ? 4 : -1;
	case OP_TYPE_VECTOR: {
		const uint32_t *c = id_def(m, d[2]);
		return c && (c[0] & 0xffff) == OP_TYPE_FLOAT && c[2] == 32 && (d[3] == 3 || d[3] == 4)
			       ? 4 * (long)d[3] : -1;
	}
	case OP_TYPE_ARRAY: {
		const uint32_t *len = id_def(m, d[3]);
		if (!len || (len[0] & 0xffff) != OP_CONSTANT || type_size(m, d[2]) < 0)
			return -1;
		return (long)len[3] * m->ids[id].array_stride;
	}
	case OP_TYPE_STRUCT: {
		long end = 0;
		for (uint32_t k = 0; k + 2 < (d[0] >> 16) && k < MAX_MEMBERS; k++) {
			long size = type_size(m, d[2 + k]);
			if (size < 0 || m->ids[id].member_offset[k] < 0)
				return -1;
			if (m->ids[id].member_offset[k] + size > end)
				end = m->ids[id].member_offset[k] + size;
		}
		return end;
	}
	default:
		return -1;
	}
}

/* One member of a C struct as sky_params.h's X-lists define it. */
struct c_member {
	const char *name;
	size_t offset, size;
};

#define PARAMS_MEMBER(name) { #name, offsetof(struct gpu_params, name), sizeof(((struct gpu_params *)0)->name) },
#define PARAMS_ARRAY(name, n) PARAMS_MEMBER(name)
static const struct c_member params_members[] = {
	SKY_PARAMS_MEMBERS(PARAMS_MEMBER, PARAMS_ARRAY, PARAMS_ARRAY)
};
#define CONSTITUENT_MEMBER(name)                                   \
	{ #name, offsetof(struct gpu_constituent, name),           \
	  sizeof(((struct gpu_constituent *)0)->name) },
static const struct c_member constituent_members[] = {
	SKY_CONSTITUENT_MEMBERS(CONSTITUENT_MEMBER)
};
#define JOB_MEMBER(name)                                           \
	{ #name, offsetof(struct gpu_aerial_job, name),            \
	  sizeof(((struct gpu_aerial_job *)0)->name) },
static const struct c_member job_members[] = {
	SKY_AERIAL_JOB_MEMBERS(JOB_MEMBER, JOB_MEMBER, JOB_MEMBER)
};

/* Compares struct type id of the module member by member with the C
 * struct's list; returns the struct's size in the module. */
static long check_struct(const struct spv *m, uint32_t id, const char *what,
			 const struct c_member *c, size_t n_c, size_t c_size)
{
	const uint32_t *d = id_def(m, id);
	if (!d || (d[0] & 0xffff) != OP_TYPE_STRUCT) {
		FAIL("%s: %s is not a struct", m->shader, what);
		return -1;
	}
	size_t n = (d[0] >> 16) - 2;
	if (n != n_c)
		FAIL("%s: %s has %zu members in the shader, %zu in C", m->shader, what, n, n_c);
	for (size_t k = 0; k < n && k < n_c && k < MAX_MEMBERS; k++) {
		const char *name = m->ids[id].member_name[k] ? m->ids[id].member_name[k] : "";
		long size = type_size(m, d[2 + k]);
		test_checks++;
		if (strcmp(name, c[k].name) || m->ids[id].member_offset[k] != (int)c[k].offset ||
		    size != (long)c[k].size)
			FAIL("%s: %s member %zu is %s at offset %d, %ld bytes in the shader; %s at %zu, %zu bytes in C",
			     m->shader, what, k, name, m->ids[id].member_offset[k], size, c[k].name,
			     c[k].offset, c[k].size);
	}
	long size = type_size(m, id);
	test_checks++;
	if (size != (long)c_size)
		FAIL("%s: %s is %ld bytes in the shader, %zu in C", m->shader, what, size, c_size);
	return size;
}

/* The uniform block: ParamsBlock { Params params; } at BINDING_PARAMS. */
static void check_block(const struct spv *m, uint32_t block)
{
	const uint32_t *d = id_def(m, block);
	CHECK(d && (d[0] & 0xffff) == OP_TYPE_STRUCT && (d[0] >> 16) == 3);
	if (!d || (d[0] & 0xffff) != OP_TYPE_STRUCT || (d[0] >> 16) != 3)
		return;
	CHECK(m->ids[block].member_offset[0] == 0);
	uint32_t params = d[2];
	check_struct(m, params, "Params", params_members, sizeof(params_members) / sizeof(params_members[0]),
		     sizeof(struct gpu_params));
	/* The constituents' struct: the element of the array member c. */
	const uint32_t *pd = id_def(m, params);
	for (uint32_t k = 0; pd && k + 2 < (pd[0] >> 16) && k < MAX_MEMBERS; k++) {
		const uint32_t *ad = id_def(m, pd[2 + k]);
		if (!m->ids[params].member_name[k] || strcmp(m->ids[params].member_name[k], "c") || !ad ||
		    (ad[0] & 0xffff) != OP_TYPE_ARRAY)
			continue;
		check_struct(m, ad[2], "Constituent", constituent_members,
			     sizeof(constituent_members) / sizeof(constituent_members[0]),
			     sizeof(struct gpu_constituent));
		test_checks++;
		if (m->ids[pd[2 + k]].array_stride != (int)sizeof(struct gpu_constituent))
			FAIL("%s: the constituents' stride is %d, sizeof(struct gpu_constituent) %zu", m->shader,
			     m->ids[pd[2 + k]].array_stride, sizeof(struct gpu_constituent));
	}
}

/* The aerial jobs: ViewBuf { uvec4 head; AerialJob job[]; } at
 * BINDING_VIEWS, job after struct gpu_aerial_head, each element struct
 * gpu_aerial_job. Returns 1 when the block is there. */
static int check_views(const struct spv *m, uint32_t block)
{
	const uint32_t *d = id_def(m, block);
	test_checks++;
	if (!d || (d[0] & 0xffff) != OP_TYPE_STRUCT || (d[0] >> 16) != 4) {
		FAIL("%s: ViewBuf is not { head, job[] }", m->shader);
		return 0;
	}
	const uint32_t *jobs = id_def(m, d[3]);
	const char *name = m->ids[block].member_name[1] ? m->ids[block].member_name[1] : "";
	test_checks++;
	if (strcmp(name, "job") || !jobs || (jobs[0] & 0xffff) != OP_TYPE_RUNTIME_ARRAY ||
	    m->ids[block].member_offset[1] != (int)sizeof(struct gpu_aerial_head) ||
	    m->ids[d[3]].array_stride != (int)sizeof(struct gpu_aerial_job)) {
		FAIL("%s: ViewBuf's jobs are %s at %d, stride %d; C: job at %zu, stride %zu", m->shader,
		     name, m->ids[block].member_offset[1], m->ids[d[3]].array_stride,
		     sizeof(struct gpu_aerial_head), sizeof(struct gpu_aerial_job));
		return 1;
	}
	check_struct(m, jobs[2], "AerialJob", job_members, sizeof(job_members) / sizeof(job_members[0]),
		     sizeof(struct gpu_aerial_job));
	return 1;
}

struct named_id {
	const char *name;
	int id;
};

/* The GLSL names of the specialization constants and their SPEC_ ids. */
static const struct named_id spec_ids[] = {
	{ "N_CONST", SPEC_N_CONST }, { "PHASE_0", SPEC_PHASE_0 }, { "PHASE_1", SPEC_PHASE_1 },
	{ "PHASE_2", SPEC_PHASE_2 }, { "PHASE_3", SPEC_PHASE_3 }, { "STORAGE_F16", SPEC_STORAGE_F16 },
	{ "MOON_LIT", SPEC_MOON_LIT }, { "GROUND_BLACK", SPEC_GROUND_BLACK }, { "T_W", SPEC_T_W },
	{ "T_H", SPEC_T_H }, { "M_W", SPEC_M_W }, { "M_H", SPEC_M_H }, { "OUT_W", SPEC_OUT_W },
	{ "OUT_H", SPEC_OUT_H }, { "OUT_D", SPEC_OUT_D }, { "STEPS", SPEC_STEPS },
	{ "MS_DIRS", SPEC_MS_DIRS }, { "MULTISCATTER_ON", SPEC_MULTISCATTER_ON },
	{ "EXP_MASK", SPEC_EXP_MASK }, { "MS_SUN_GROUP", SPEC_MS_SUN_GROUP },
	{ "SV_AZ_GROUP", SPEC_SV_AZ_GROUP }, { "ITER_FIRST", SPEC_ITER_FIRST },
	{ "MOMENT_LOBE", SPEC_MOMENT_LOBE }, { "DELTA_LOBE", SPEC_DELTA_LOBE },
	{ "PACK_MASK", SPEC_PACK_MASK }, { "MS_LANES", SPEC_MS_LANES },
	{ "LOOKUP_IMAGES", SPEC_LOOKUP_IMAGES }, { "MS_UNIFORM", SPEC_MS_UNIFORM },
	{ "CLOUD_LAYERS", SPEC_CLOUD_LAYERS }, { "SHADOW_W", SPEC_SHADOW_W }, { "CLOUD_W", SPEC_CLOUD_W },
	{ "SV_EYE_UNDER", SPEC_SV_EYE_UNDER },
	{ "TERRAIN", SPEC_TERRAIN }, { "SV_KEPT", SPEC_SV_KEPT },
	{ "CLOUD_PHASES", SPEC_CLOUD_PHASES },
	/* layout(local_size_x_id, local_size_y_id): glslang leaves the
	 * workgroup size's constants without a name. */
	{ "", SPEC_LOCAL_X }, { "", SPEC_LOCAL_Y },
};
#define N_SPEC_IDS (sizeof(spec_ids) / sizeof(spec_ids[0]))

/* The descriptors by block name (buffers) or variable name (texel
 * buffers) and their BINDING_ numbers. */
static const struct named_id bindings[] = {
	{ "ParamsBlock", BINDING_PARAMS }, { "TransmittanceBuf", BINDING_TRANSMITTANCE },
	{ "MultiscatterBuf", BINDING_MULTISCATTER }, { "SkyviewBuf", BINDING_SKYVIEW },
	{ "AerialBuf", BINDING_AERIAL }, { "AerialTexels", BINDING_AERIAL },
	{ "TransmittanceHalves", BINDING_TRANSMITTANCE },
	{ "TransmittanceTexels", BINDING_TRANSMITTANCE },
	{ "MultiscatterQuads", BINDING_MULTISCATTER }, { "SkyviewQuads", BINDING_SKYVIEW },
	{ "AerialQuads", BINDING_AERIAL },
	{ "PackBuf", BINDING_PACK }, { "TransmittanceTex", BINDING_TRANSMITTANCE_TEX },
	{ "MultiscatterTex", BINDING_MULTISCATTER_TEX }, { "ViewBuf", BINDING_VIEWS },
	{ "ColumnBuf", BINDING_COLUMNS }, { "IterBuf", BINDING_ITERATE }, { "MomentBuf", BINDING_MOMENT },
	{ "MomentTex", BINDING_MOMENT_TEX }, { "ColumnTex", BINDING_COLUMNS_TEX },
	{ "AerialTex", BINDING_AERIAL_TEX }, { "TransmittanceImg", BINDING_TRANSMITTANCE_IMG },
	{ "MultiscatterImg", BINDING_MULTISCATTER_IMG },
	{ "CloudBlock", BINDING_CLOUDS }, { "CloudTexels", BINDING_CLOUD }, { "CloudTex", BINDING_CLOUD_TEX },
	{ "ShadowTexels", BINDING_SHADOW }, { "ShadowTex", BINDING_SHADOW_TEX },
	{ "TerrainTexels", BINDING_TERRAIN }, { "MultiscatterBlock", BINDING_MULTISCATTER_UBO },
	{ "SkyviewLight", BINDING_SV_LIGHT },
};

static const struct named_id *find(const struct named_id *list, size_t n, const char *name)
{
	for (size_t i = 0; i < n; i++)
		if (!strcmp(list[i].name, name))
			return &list[i];
	return NULL;
}

/* The specialization constant of that name; an unnamed one (the
 * workgroup size's) by its id among the unnamed. */
static const struct named_id *find_spec(const char *name, int id)
{
	for (size_t i = 0; i < N_SPEC_IDS; i++)
		if (!strcmp(spec_ids[i].name, name) && (*name || spec_ids[i].id == id))
			return &spec_ids[i];
	return NULL;
}

/* Checks one module; marks the specialization constants it declares in seen. */
static void check_module(const struct spv *m, int seen[SPEC_COUNT])
{
	int blocks = 0, views = 0;
	for (uint32_t i = 0; i < m->bound; i++) {
		const struct spv_id *id = &m->ids[i];
		if (id->spec_id >= 0) {
			const struct named_id *s = find_spec(id_name(m, i), id->spec_id);
			test_checks++;
			if (!s || s->id != id->spec_id || id->spec_id >= SPEC_COUNT)
				FAIL("%s: constant %s has constant_id %d, sky_params.h says %d (SPEC_COUNT %d)",
				     m->shader, id_name(m, i), id->spec_id, s ? s->id : -1, SPEC_COUNT);
			else
				seen[id->spec_id] = 1;
		}
		if (id->binding < 0 || !id->def || (id->def[0] & 0xffff) != OP_VARIABLE)
			continue;
		/* A block's variable points to the block's struct; a texel
		 * buffer's has only its own name. */
		const uint32_t *ptr = id_def(m, id->def[1]);
		uint32_t pointee = ptr && (ptr[0] & 0xffff) == OP_TYPE_POINTER ? ptr[3] : 0;
		const uint32_t *pd = id_def(m, pointee);
		bool is_block = pd && (pd[0] & 0xffff) == OP_TYPE_STRUCT;
		const char *name = is_block ? id_name(m, pointee) : id_name(m, i);
		const struct named_id *b = find(bindings, sizeof(bindings) / sizeof(bindings[0]), name);
		test_checks++;
		if (!b || b->id != id->binding)
			FAIL("%s: %s has binding %d, sky_params.h says %d", m->shader, name, id->binding,
			     b ? b->id : -1);
		if (is_block && id->binding == BINDING_PARAMS) {
			check_block(m, pointee);
			blocks++;
		}
		if (is_block && id->binding == BINDING_VIEWS)
			views += check_views(m, pointee);
	}
	/* The two aerial passes read the jobs, nothing else does. */
	int reads_jobs = !strcmp(m->shader, "aerial") || !strcmp(m->shader, "aerial_resample");
	test_checks++;
	if (views != reads_jobs)
		FAIL("%s: %d job buffers at BINDING_VIEWS", m->shader, views);
	/* Every pass reads the uniform block (load_params()), but the pack
	 * pass, which reads only the tables and struct gpu_pack, the views'
	 * resampling, which reads only the aerial jobs and texels, and the
	 * coverage table's, which reads only the cloud block. */
	test_checks++;
	if (blocks != (strcmp(m->shader, "pack") && strcmp(m->shader, "aerial_resample") &&
				       strcmp(m->shader, "cloud") ? 1 : 0))
		FAIL("%s: %d uniform blocks at BINDING_PARAMS", m->shader, blocks);
}

int main(void)
{
	int seen[SPEC_COUNT] = { 0 };
	for (int s = 0; s < SHADER_COUNT; s++) {
		struct spv m;
		if (spv_load(&shader_code[s], &m) < 0) {
			FAIL("%s: not a SPIR-V module", shader_code[s].name);
			free(m.ids);
			continue;
		}
		check_module(&m, seen);
		free(m.ids);
	}
	/* Every id sky_params.h names is some shader's. */
	for (size_t i = 0; i < N_SPEC_IDS; i++) {
		test_checks++;
		if (!seen[spec_ids[i].id])
			FAIL("no shader declares %s (constant_id %d)", spec_ids[i].name, spec_ids[i].id);
	}
	return test_report("test_params");
}
