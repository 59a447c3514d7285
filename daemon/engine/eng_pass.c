/* eng_pass.c - the compute passes as a table: what each reads and writes,
 * when a computation runs it, its specialization and workgroups at the
 * engine's grain; planning a computation from the table, recording it
 * into one command buffer with the barriers its dependencies need, and
 * reading back each pass's GPU time.
 *
 * How to add a pass (a cloud coverage table, a shadow map):
 *  1. its shader: shaders/NAME.comp, named in SKYD_SHADERS
 *     (shaders/CMakeLists.txt) and in shaders.c/shaders.h (SHADER_*);
 *  2. its buffers, if it writes something new: a RES_ bit below, the
 *     buffer in eng_tables.c (ensure_internal) and its binding in
 *     shaders/sky_params.h (BINDING_*, bind_buffers);
 *  3. a PASS_ id in eng_internal.h, placed after every pass whose output
 *     it reads (passes are recorded in id order);
 *  4. a row in pass_rows: the shader, the table whose GPU time it counts
 *     in, the resources it reads and writes, and a plan function that says
 *     whether a computation runs it, with which specialization constants
 *     and over how many workgroups at the engine's grain (e->grain); a
 *     record function only if it is more than one dispatch.
 * The barriers come from the rows' reads and writes (none between passes
 * that share nothing, so a GPU may overlap them), the timestamps and the
 * pipelines' cache from the pass's id and shader. */
#include "eng_internal.h"

#include <math.h>
#include <string.h>

/* What passes read and write, for the barriers between them. */
enum {
	RES_TRANSMITTANCE = 1 << STATE_TRANSMITTANCE,	/* a table's buffer: RES_TABLE(t) */
	RES_MULTISCATTER = 1 << STATE_MULTISCATTER,
	RES_SKYVIEW = 1 << STATE_SKYVIEW,
	RES_AERIAL = 1 << STATE_AERIAL,
	RES_COLUMNS = 1 << 4,		/* the column densities */
	RES_MOMENT = 1 << 5,		/* the shape of the multiply scattered light */
	RES_ITERATE = 1 << 6,		/* the iteration's scratch */
	RES_PACK = 1 << 7,		/* struct gpu_pack: the ranges and scales */
	RES_IMAGES = 1 << 8,		/* the lookups as sampled images */
	RES_CLOUD = 1 << 9,		/* the cloud coverage table */
	RES_SHADOW = 1 << 10,		/* the shadow maps */
};
#define RES_TABLES (RES_TRANSMITTANCE | RES_MULTISCATTER | RES_SKYVIEW | RES_AERIAL)
/* What the passes that look the lower tables up read. */
#define RES_LOOKUPS (RES_TRANSMITTANCE | RES_MULTISCATTER | RES_MOMENT | RES_COLUMNS | RES_IMAGES)

struct pass_row {
	const char *name;
	int shader;		/* SHADER_*; -1: no dispatch, record only */
	int table;		/* whose GPU time it counts in; -1: the last table of the mask */
	uint32_t reads, writes;	/* RES_* */
	/* Whether the computation pl runs it; if so its key and groups (the
	 * pipeline is looked up from the key). base: eng_fill_params's. */
	void (*plan)(struct eng *e, const struct sky_state *s, const struct spec *base,
		     struct plan *pl, struct pass_run *ret);
	/* Its commands between its timestamps; NULL: one dispatch of groups. */
	void (*record)(struct eng *e, const struct sky_state *s, const struct plan *pl,
		       const struct pass_run *run);
};

static uint32_t div_up(uint32_t a, uint32_t b)
{
	return (a + b - 1) / b;
}

/* Workgroups of 8 x 8 invocations over a table, each invocation
 * computing group texels of a row. */
static void table_groups(const struct sky_state *s, int t, uint32_t group, struct pass_run *r)
{
	const struct state_table_quality *q = &s->quality.t[t];
	r->groups[0] = div_up(div_up(q->width, group), 8);
	r->groups[1] = div_up(q->height, 8);
	r->groups[2] = 1;
}

/* The column densities are recomputed only when what they depend on
 * changed; the same inputs give the same bits, so a table made from kept
 * columns is the one a fresh engine makes. The pass writes the
 * transmittance table too (the storage is in its pipeline's key, not in
 * the columns'). */
static void plan_columns(struct eng *e, const struct sky_state *s, const struct spec *base,
			 struct plan *pl, struct pass_run *r)
{
	r->key = eng_column_spec(base, s);
	eng_column_key(e->params.map, &r->key, &pl->key);
	r->key.v[SPEC_STORAGE_F16] = base->v[SPEC_STORAGE_F16];
	r->on = (pl->mask & STATE_BIT(STATE_TRANSMITTANCE)) &&
		(!e->columns_valid || memcmp(&pl->key, &e->column_key, sizeof(pl->key)));
	table_groups(s, STATE_TRANSMITTANCE, 1, r);
}

/* From kept columns only: the column pass writes the table with them. */
static void plan_transmittance(struct eng *e, const struct sky_state *s, const struct spec *base,
			       struct plan *pl, struct pass_run *r)
{
	r->on = (pl->mask & STATE_BIT(STATE_TRANSMITTANCE)) && !pl->run[PASS_COLUMNS].on;
	r->key = eng_pass_spec(base, s, STATE_TRANSMITTANCE, &e->grain);
	table_groups(s, STATE_TRANSMITTANCE, 1, r);
}

/* The CPU grain's invocations each take ms_sun_group texels of a row; the
 * wide grain's workgroups each one texel (msgrid.glsl). */
static void ms_groups(const struct eng *e, const struct sky_state *s, struct pass_run *r)
{
	const struct state_table_quality *q = &s->quality.t[STATE_MULTISCATTER];
	if (e->grain.ms_wide) {
		r->groups[0] = q->width;
		r->groups[1] = q->height;
		r->groups[2] = 1;
	} else {
		table_groups(s, STATE_MULTISCATTER, e->grain.ms_sun_group, r);
	}
}

static void plan_multiscatter(struct eng *e, const struct sky_state *s, const struct spec *base,
			      struct plan *pl, struct pass_run *r)
{
	r->on = pl->mask & STATE_BIT(STATE_MULTISCATTER);
	r->key = eng_pass_spec(base, s, STATE_MULTISCATTER, &e->grain);
	ms_groups(e, s, r);
}

/* The iteration of psi_ms: its first step recovers L2 from the table, the
 * later ones read it back (SPEC_ITER_FIRST); run->key is the first's. */
static void plan_msiterate(struct eng *e, const struct sky_state *s, const struct spec *base,
			   struct plan *pl, struct pass_run *r)
{
	pl->iterations = (pl->mask & STATE_BIT(STATE_MULTISCATTER)) ? state_multiscatter_iterations(s) : 0;
	r->on = pl->iterations > 0;
	r->key = eng_pass_spec(base, s, STATE_MULTISCATTER, &e->grain);
	r->key.v[SPEC_ITER_FIRST] = 1;
	ms_groups(e, s, r);
}

static void plan_skyview(struct eng *e, const struct sky_state *s, const struct spec *base,
			 struct plan *pl, struct pass_run *r)
{
	r->on = pl->mask & STATE_BIT(STATE_SKYVIEW);
	r->key = eng_pass_spec(base, s, STATE_SKYVIEW, &e->grain);
	r->key.v[SPEC_SV_EYE_UNDER] = pl->eye_under;
	r->key.v[SPEC_SV_KEPT] = eng_sv_kept(e, s, pl, &r->key);
	table_groups(s, STATE_SKYVIEW, e->grain.sv_az_group, r);
}

/* Every aerial march in one dispatch, z the job, over the rows of
 * aerial_width invocations the volume needs, or a panorama's columns
 * where they are more. */
static void plan_aerial(struct eng *e, const struct sky_state *s, const struct spec *base,
			struct plan *pl, struct pass_run *r)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	uint32_t rows = div_up(e->aplan.width * e->aplan.height, q->width);
	r->on = pl->mask & STATE_BIT(STATE_AERIAL);
	r->key = eng_pass_spec(base, s, STATE_AERIAL, &e->grain);
	table_groups(s, STATE_AERIAL, 1, r);
	r->groups[1] = div_up(e->aplan.n_panoramas && rows > q->height ? rows : q->height, 8);
	r->groups[2] = pl->aerial_march;
}

/* Every resampled volume in one dispatch, z the job. */
static void plan_resample(struct eng *e, const struct sky_state *s, const struct spec *base,
			  struct plan *pl, struct pass_run *r)
{
	r->on = (pl->mask & STATE_BIT(STATE_AERIAL)) && pl->aerial_resample;
	r->key = eng_pass_spec(base, s, STATE_AERIAL, &e->grain);
	table_groups(s, STATE_AERIAL, 1, r);
	r->groups[2] = pl->aerial_resample;
}

/* The binary16 copies of the tables of the mask (all but transmittance,
 * which packs itself), each invocation of 64 packing up to 16 texels of
 * the largest of them. */
static void plan_pack(struct eng *e, const struct sky_state *s, const struct spec *base,
		      struct plan *pl, struct pass_run *r)
{
	uint64_t most = 0;
	(void)base;
	memset(&r->key, 0, sizeof(r->key));
	r->key.v[SPEC_PACK_MASK] = (int32_t)(pl->mask & STATE_ALL_TABLES & ~STATE_BIT(STATE_TRANSMITTANCE));
	r->on = s->quality.storage == STATE_F16 && r->key.v[SPEC_PACK_MASK];
	for (int t = 0; t < STATE_N_TABLES; t++)
		if (r->key.v[SPEC_PACK_MASK] & STATE_BIT(t) && eng_table_texels(e, s, t) > most)
			most = eng_table_texels(e, s, t);
	uint64_t groups = (most + 64 * 16 - 1) / (64 * 16);
	r->groups[0] = groups > e->limits.maxComputeWorkGroupCount[0]
			       ? e->limits.maxComputeWorkGroupCount[0] : (uint32_t)groups;
	r->groups[1] = r->groups[2] = 1;
}

/* Sky-view and aerial perspective read the lookups through images at
 * that grain: copied after the tables were computed (or where the images
 * lack them since), before the passes that read them. eng_submit_to
 * keeps images_valid. */
static void plan_lookup_images(struct eng *e, const struct sky_state *s, const struct spec *base,
			       struct plan *pl, struct pass_run *r)
{
	uint32_t readers = STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL);
	(void)s;
	(void)base;
	r->on = e->grain.lookup_images && (pl->mask & readers) &&
		((pl->mask & ENG_LOOKUP_TABLES) || !e->images_valid);
}

/* The copies of the lookup tables into their images, from and back to
 * the layout the shaders sample. */
static void record_lookup_images(struct eng *e, const struct sky_state *s, const struct plan *pl,
				 const struct pass_run *run)
{
	const VkMemoryBarrier written = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
		.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT };
	VkImageMemoryBarrier to[N_LOOKUPS], back[N_LOOKUPS];
	(void)s;
	(void)pl;
	(void)run;

	for (int t = 0; t < N_LOOKUPS; t++) {
		to[t] = (VkImageMemoryBarrier){ .sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER,
			.srcAccessMask = VK_ACCESS_SHADER_READ_BIT, .dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
			.oldLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
			.newLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
			.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED, .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
			.image = e->lookup_image[t].img, .subresourceRange = { VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1 } };
		back[t] = to[t];
		back[t].srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
		back[t].dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
		back[t].oldLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
		back[t].newLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
	}
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
				   VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &written, 0, NULL, N_LOOKUPS, to);
	for (int t = 0; t < N_LOOKUPS; t++) {
		VkBufferImageCopy c = { .imageSubresource = { VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1 },
			.imageExtent = { e->lookup_image[t].width, e->lookup_image[t].height, 1 } };
		e->vk.vkCmdCopyBufferToImage(e->cmd, e->table[t].buf, e->lookup_image[t].img,
					     VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &c);
	}
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0,
				   0, NULL, 0, NULL, N_LOOKUPS, back);
}

/* The steps of the iteration of psi_ms: each writes the next table into
 * the scratch buffer, which is then copied over the table (later passes
 * and the next step read it through the lookup view). With storage=f16
 * the table's range is cleared before the last step, which records the
 * range of what it stores: the table's. */
static void record_iteration(struct eng *e, const struct sky_state *s, const struct plan *pl,
			     const struct pass_run *run)
{
	const VkMemoryBarrier to_copy = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_SHADER_READ_BIT,
		.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT };
	const VkMemoryBarrier to_read = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
		.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT };

	for (uint32_t i = 0; i < pl->iterations; i++) {
		if (i == pl->iterations - 1 && s->quality.storage == STATE_F16) {
			e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
						   VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &to_copy, 0, NULL, 0,
						   NULL);
			e->vk.vkCmdFillBuffer(e->cmd, e->pack.buf,
					      offsetof(struct gpu_pack, max_bits[STATE_MULTISCATTER]),
					      sizeof(uint32_t), 0);
			e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
						   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &to_read, 0, NULL,
						   0, NULL);
		}
		e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE,
					i > 0 ? pl->iterate_later : run->pipe);
		e->vk.vkCmdDispatch(e->cmd, run->groups[0], run->groups[1], run->groups[2]);
		e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
					   VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &to_copy, 0, NULL, 0, NULL);
		VkBufferCopy c = { 0, 0, eng_float_bytes(e, s, STATE_MULTISCATTER) };
		e->vk.vkCmdCopyBuffer(e->cmd, e->ms_iterate.buf, e->table[STATE_MULTISCATTER].buf, 1, &c);
		e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
					   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &to_read, 0, NULL, 0,
					   NULL);
	}
}

/* The most march steps of a shadow map's ray through one layer: it takes
 * two a coverage texel its piece crosses, at least four (shadow.comp). */
#define SHADOW_STEPS 32

/* SPEC_CLOUD_PHASES for the n drawn layers of c: whether ice (cirrus) and
 * water layers are both drawn, and which lies above the other: the one
 * whose top is higher, where their heights overlap. Below every layer the
 * order does not matter (the whole of each is above); inside, a point
 * reads the upper's depth first. */
static int32_t cloud_phases(const struct gpu_clouds *c, int n)
{
	float ice_top = -INFINITY, water_top = -INFINITY;
	for (int i = 0; i < n; i++) {
		float *top = c->layer[i].type == SKYCLOUD_CIRRUS ? &ice_top : &water_top;
		*top = fmaxf(*top, c->layer[i].top_km);
	}
	if (!(ice_top > -INFINITY) || !(water_top > -INFINITY))
		return CLOUD_PHASES_ONE;
	return ice_top >= water_top ? CLOUD_PHASES_ICE_OVER : CLOUD_PHASES_WATER_OVER;
}

/* The cloud passes' constants: the layers and the tables' sizes, nothing
 * of the atmosphere (shadow.comp reads the planet's radius from the
 * uniform block), so that a change of the sky alone reuses them. */
static struct spec cloud_spec(const struct sky_state *s, const struct plan *pl)
{
	struct spec k;
	memset(&k, 0, sizeof(k));
	k.v[SPEC_CLOUD_LAYERS] = pl->n_clouds;
	k.v[SPEC_CLOUD_W] = (int32_t)s->quality.cloud_width;
	k.v[SPEC_SHADOW_W] = (int32_t)s->quality.shadow_width;
	k.v[SPEC_STEPS] = SHADOW_STEPS;
	k.v[SPEC_TERRAIN] = pl->clouds.TERRAIN_HALF_KM > 0.0f;
	return k;
}

static void plan_cloud(struct eng *e, const struct sky_state *s, const struct spec *base,
		       struct plan *pl, struct pass_run *r)
{
	(void)e;
	(void)base;
	r->on = pl->n_clouds > 0 && (pl->mask & STATE_BIT(STATE_CLOUD_COVERAGE));
	r->key = cloud_spec(s, pl);
	r->groups[0] = r->groups[1] = div_up(s->quality.cloud_width, 8);
	r->groups[2] = 1;
}

/* A map per light that lights: the moon's where it does. */
static void plan_shadow(struct eng *e, const struct sky_state *s, const struct spec *base,
			struct plan *pl, struct pass_run *r)
{
	(void)e;
	r->on = eng_shadow_casters(s) && (pl->mask & STATE_BIT(STATE_CLOUD_SHADOW));
	r->key = cloud_spec(s, pl);
	/* The ice depths are the shadow pass's alone of the cloud passes. */
	r->key.v[SPEC_CLOUD_PHASES] = base->v[SPEC_CLOUD_PHASES];
	r->groups[0] = r->groups[1] = div_up(s->quality.shadow_width, 8);
	r->groups[2] = s->moon.illuminance_lx > 0.0 ? 2 : 1;
}

/* The maps. An unlit moon's is not drawn; its slice is cleared instead,
 * once, so that the table holds the same bits on every host whatever the
 * set held before: a moonlit map, or nothing yet. */
static void record_shadow(struct eng *e, const struct sky_state *s, const struct plan *pl,
			  const struct pass_run *run)
{
	(void)s;
	(void)pl;
	e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, run->pipe);
	e->vk.vkCmdDispatch(e->cmd, run->groups[0], run->groups[1], run->groups[2]);
	if (run->groups[2] > 1 || e->ct.moon_zero)
		return;
	/* The fill and the dispatch write disjoint slices; the passes after
	 * read the table, the host reads it after the final barrier. */
	const VkMemoryBarrier to_read = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT, .dstAccessMask = VK_ACCESS_SHADER_READ_BIT };
	VkDeviceSize slice_bytes = e->shadow_map_bytes / 2;
	e->vk.vkCmdFillBuffer(e->cmd, e->ct.shadow.buf, slice_bytes, slice_bytes, 0);
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
				   0, 1, &to_read, 0, NULL, 0, NULL);
}

/* The passes in recording order (enum pass). */
static const struct pass_row pass_rows[N_PASSES] = {
	[PASS_COLUMNS] = { "columns", SHADER_COLUMNS, STATE_TRANSMITTANCE, 0,
			   RES_COLUMNS | RES_TRANSMITTANCE, plan_columns, NULL },
	[PASS_TRANSMITTANCE] = { "transmittance", SHADER_TRANSMITTANCE, STATE_TRANSMITTANCE,
				 RES_COLUMNS, RES_TRANSMITTANCE, plan_transmittance, NULL },
	[PASS_MULTISCATTER] = { "multiscatter", SHADER_MULTISCATTER, STATE_MULTISCATTER,
				RES_TRANSMITTANCE | RES_COLUMNS,
				RES_MULTISCATTER | RES_MOMENT | RES_PACK, plan_multiscatter, NULL },
	[PASS_MSITERATE] = { "msiterate", SHADER_MSITERATE, STATE_MULTISCATTER,
			     RES_LOOKUPS | RES_ITERATE,
			     RES_MULTISCATTER | RES_MOMENT | RES_ITERATE | RES_PACK, plan_msiterate,
			     record_iteration },
	/* Counted with the last table, as the pack pass. */
	[PASS_LOOKUP_IMAGES] = { "lookup_images", -1, -1, RES_TRANSMITTANCE | RES_MULTISCATTER,
				 RES_IMAGES, plan_lookup_images, record_lookup_images },
	/* Counted with sky-view, whose change made them. */
	[PASS_CLOUD] = { "cloud", SHADER_CLOUD, STATE_SKYVIEW, 0, RES_CLOUD, plan_cloud, NULL },
	[PASS_SHADOW] = { "shadow", SHADER_SHADOW, STATE_SKYVIEW, RES_CLOUD, RES_SHADOW, plan_shadow,
			  record_shadow },
	[PASS_SKYVIEW] = { "skyview", SHADER_SKYVIEW, STATE_SKYVIEW, RES_LOOKUPS | RES_SHADOW,
			   RES_SKYVIEW | RES_PACK, plan_skyview, NULL },
	[PASS_AERIAL] = { "aerial", SHADER_AERIAL, STATE_AERIAL, RES_LOOKUPS | RES_SHADOW,
			  RES_AERIAL | RES_PACK, plan_aerial, NULL },
	[PASS_RESAMPLE] = { "aerial_resample", SHADER_AERIAL_RESAMPLE, STATE_AERIAL, RES_AERIAL,
			    RES_AERIAL | RES_PACK, plan_resample, NULL },
	[PASS_PACK] = { "pack", SHADER_PACK, -1, RES_TABLES | RES_PACK, RES_TABLES | RES_PACK,
			plan_pack, NULL },
};

/* The pipeline of shader with key into *ret, or VK_NULL_HANDLE with the
 * variant ordered. */
static void get_pipeline(struct eng *e, int shader, const struct spec *key, VkPipeline *ret)
{
	*ret = VK_NULL_HANDLE;
	for (int i = 0; i < e->n_pipes[shader]; i++)
		if (!memcmp(&e->pipes[shader][i].key, key, sizeof(*key))) {
			*ret = e->pipes[shader][i].pipe;
			return;
		}
	for (int i = 0; i < e->n_orders; i++)
		if (e->orders[i].shader == shader && !memcmp(&e->orders[i].key, key, sizeof(*key)))
			return;
	e->orders[e->n_orders++] = (struct pipeline_order){ shader, *key };
}

static VkResult make_pipeline(struct eng *e, const struct pipeline_order *o)
{
	if (e->n_pipes[o->shader] == MAX_PIPELINES) {
		/* Evict the oldest variant; no work is in flight here. */
		e->vk.vkDestroyPipeline(e->dev, e->pipes[o->shader][0].pipe, NULL);
		memmove(&e->pipes[o->shader][0], &e->pipes[o->shader][1],
			sizeof(e->pipes[o->shader][0]) * (MAX_PIPELINES - 1));
		e->n_pipes[o->shader]--;
	}
	VkSpecializationMapEntry map[N_SPEC];
	for (uint32_t i = 0; i < N_SPEC; i++)
		map[i] = (VkSpecializationMapEntry){ i, i * 4, 4 };
	/* Every constant for every pass: Vulkan ignores the ids a shader does
	 * not declare. */
	VkSpecializationInfo si = { N_SPEC, map, sizeof(o->key.v), o->key.v };
	VkComputePipelineCreateInfo ci = { .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
		.stage = { .sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
			   .stage = VK_SHADER_STAGE_COMPUTE_BIT, .module = e->modules[o->shader],
			   .pName = "main", .pSpecializationInfo = &si },
		.layout = e->pipe_layout };
	VkPipeline p;
	VkResult r = e->vk.vkCreateComputePipelines(e->dev, e->pipeline_cache, 1, &ci, NULL, &p);
	if (r != VK_SUCCESS)
		return r;
	e->pipelines_created++;
	e->pipes[o->shader][e->n_pipes[o->shader]++] = (struct pipeline){ o->key, p };
	return VK_SUCCESS;
}

VkResult eng_make_orders(struct eng *e)
{
	VkResult r = VK_SUCCESS;
	for (int i = 0; i < e->n_orders && r == VK_SUCCESS; i++)
		r = make_pipeline(e, &e->orders[i]);
	e->n_orders = 0;
	return r;
}

void eng_free_pipelines(struct eng *e)
{
	for (int t = 0; t < SHADER_COUNT; t++) {
		for (int i = 0; i < e->n_pipes[t]; i++)
			e->vk.vkDestroyPipeline(e->dev, e->pipes[t][i].pipe, NULL);
		e->n_pipes[t] = 0;
	}
}

/* Whether run's workgroups fit the device: 0, or -EINVAL naming pass p. */
static int check_groups(const struct eng *e, int p, const struct pass_run *run, char *err,
			size_t err_size)
{
	for (int i = 0; i < 3; i++)
		if (run->groups[i] > e->limits.maxComputeWorkGroupCount[i]) {
			eng_set_err(err, err_size, "%s: %u workgroups along axis %d exceed the device's %u",
				pass_rows[p].name, run->groups[i], i, e->limits.maxComputeWorkGroupCount[i]);
			return -EINVAL;
		}
	return 0;
}

/* Whether the observer (km) is under the casters' top: the terrain's
 * highest texel or a drawn layer's top. */
static bool eye_under_casters(const struct gpu_clouds *c, int n_clouds, float observer_km)
{
	float top_km = c->TERRAIN_TOP_KM;
	for (int i = 0; i < n_clouds; i++)
		top_km = fmaxf(top_km, c->layer[i].top_km);
	return observer_km < top_km;
}

int eng_make_plan(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		  uint32_t mask, struct gpu_params *params, struct plan *pl, char *err,
		  size_t err_size)
{
	struct spec base;
	int rc = 0;

	memset(pl, 0, sizeof(*pl));
	e->n_orders = 0;
	pl->mask = mask;
	pl->last_table = -1;
	for (int t = 0; t < STATE_N_TABLES; t++)
		if (mask & STATE_BIT(t))
			pl->last_table = t;
	eng_fill_params(e, s, lights, params, &base);
	pl->n_clouds = eng_fill_clouds(s, lights, &pl->clouds);
	pl->mask = mask = eng_cloud_mask(e, s, &pl->clouds, pl->n_clouds, mask);
	base.v[SPEC_CLOUD_LAYERS] = pl->n_clouds;
	base.v[SPEC_SHADOW_W] = eng_shadow_casters(s) ? (int32_t)s->quality.shadow_width : 0;
	base.v[SPEC_CLOUD_W] = pl->n_clouds ? (int32_t)s->quality.cloud_width : 0;
	base.v[SPEC_CLOUD_PHASES] = base.v[SPEC_SHADOW_W] ? cloud_phases(&pl->clouds, pl->n_clouds) : 0;
	pl->eye_under = base.v[SPEC_SHADOW_W] > 0 && eye_under_casters(&pl->clouds, pl->n_clouds,
								       params->OBSERVER_KM);
	memcpy(e->clouds.map, &pl->clouds, sizeof(pl->clouds));
	memcpy(pl->sv_key.planet, params->planet, sizeof(pl->sv_key.planet));
	pl->sv_key.min_steps = params->SKYVIEW_MIN_STEPS;
	pl->sv_key.clouds = pl->clouds;
	/* The column pass's key compares the uniform block as uploaded. */
	memcpy(e->params.map, params, sizeof(*params));
	eng_fill_views(s, &e->aplan, e->panorama_offset / 16, e->views.map, &pl->aerial_march,
		       &pl->aerial_resample);
	for (int p = 0; p < N_PASSES && rc == 0; p++) {
		struct pass_run *run = &pl->run[p];
		pass_rows[p].plan(e, s, &base, pl, run);
		if (!run->on)
			continue;
		rc = check_groups(e, p, run, err, err_size);
		if (rc == 0 && pass_rows[p].shader >= 0)
			get_pipeline(e, pass_rows[p].shader, &run->key, &run->pipe);
	}
	if (rc == 0 && pl->run[PASS_SKYVIEW].on && pl->run[PASS_SKYVIEW].key.v[SPEC_SV_KEPT] == SV_KEPT_WRITE) {
		/* The next change in the cell reads what this one keeps: its
		 * variant is made with this one's, one wait for both. */
		struct spec later = pl->run[PASS_SKYVIEW].key;
		VkPipeline read;
		later.v[SPEC_SV_KEPT] = SV_KEPT_READ;
		get_pipeline(e, SHADER_SKYVIEW, &later, &read);
	}
	if (rc == 0 && pl->run[PASS_MSITERATE].on) {
		struct spec later = pl->run[PASS_MSITERATE].key;
		later.v[SPEC_ITER_FIRST] = 0;
		get_pipeline(e, SHADER_MSITERATE, &later, &pl->iterate_later);
	}
	return rc;
}

void eng_record_passes(struct eng *e, const struct sky_state *s, const struct plan *pl)
{
	const VkMemoryBarrier after = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT,
		.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
				 VK_ACCESS_UNIFORM_READ_BIT };
	/* What passes since the last barrier wrote and read. */
	uint32_t written = 0, read = 0;

	for (int p = 0; p < N_PASSES; p++) {
		const struct pass_row *row = &pass_rows[p];
		const struct pass_run *run = &pl->run[p];
		if (!run->on)
			continue;
		/* A pass waits for the writes it reads or overwrites, and for
		 * the reads of what it overwrites. */
		if (((row->reads | row->writes) & written) || (row->writes & read)) {
			e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
						   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &after, 0,
						   NULL, 0, NULL);
			written = read = 0;
		}
		if (e->timestamps)
			e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, e->queries,
						  2 * (uint32_t)p);
		if (row->record) {
			row->record(e, s, pl, run);
		} else {
			e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, run->pipe);
			e->vk.vkCmdDispatch(e->cmd, run->groups[0], run->groups[1], run->groups[2]);
		}
		if (e->timestamps)
			e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, e->queries,
						  2 * (uint32_t)p + 1);
		written |= row->writes;
		read |= row->reads;
	}
}

int eng_pass_times(struct eng *e, const struct plan *pl, struct eng_timing *t, char *err,
		   size_t err_size)
{
	int rc = 0;

	for (int p = 0; p < N_PASSES && e->timestamps; p++) {
		uint64_t ts[2];
		if (!pl->run[p].on)
			continue;
		VK_TRY(e->vk.vkGetQueryPoolResults(e->dev, e->queries, 2 * (uint32_t)p, 2, sizeof(ts), ts,
						   sizeof(uint64_t),
						   VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
		double ms = (double)(ts[1] - ts[0]) * e->timestamp_period_ns * 1e-6;
		int table = pass_rows[p].table >= 0 ? pass_rows[p].table : pl->last_table;
		if (p == PASS_COLUMNS)
			t->columns_ms = ms;
		else if (p == PASS_CLOUD)
			t->cloud_ms = ms;
		else if (p == PASS_SHADOW)
			t->shadow_ms = ms;
		if (table >= 0)
			t->table_ms[table] += ms;
	}
fail:
	return rc;
}
