/* eng_run.c - running the passes: the pipeline cache, the tables'
 * buffers, recording and submitting the command buffer, and completion. */
#include "eng_internal.h"

#include <errno.h>
#include <poll.h>
#include <stddef.h>
#include <string.h>
#include <unistd.h>

static double elapsed_ms(const struct timespec *a, const struct timespec *b)
{
	return (b->tv_sec - a->tv_sec) * 1e3 + (b->tv_nsec - a->tv_nsec) * 1e-6;
}

static int get_pipeline(struct eng *e, int t, const struct spec *key, VkPipeline *ret,
			char *err, size_t err_size)
{
	int rc = 0;
	for (int i = 0; i < e->n_pipes[t]; i++)
		if (!memcmp(&e->pipes[t][i].key, key, sizeof(*key))) {
			*ret = e->pipes[t][i].pipe;
			return 0;
		}
	if (e->n_pipes[t] == MAX_PIPELINES) {
		/* Evict the oldest variant; no work is in flight here. */
		e->vk.vkDestroyPipeline(e->dev, e->pipes[t][0].pipe, NULL);
		memmove(&e->pipes[t][0], &e->pipes[t][1], sizeof(e->pipes[t][0]) * (MAX_PIPELINES - 1));
		e->n_pipes[t]--;
	}
	VkSpecializationMapEntry map[N_SPEC];
	for (uint32_t i = 0; i < N_SPEC; i++)
		map[i] = (VkSpecializationMapEntry){ i, i * 4, 4 };
	/* Every constant for every pass: Vulkan ignores the ids a shader does
	 * not declare. */
	VkSpecializationInfo si = { N_SPEC, map, sizeof(key->v), key->v };
	VkComputePipelineCreateInfo ci = { .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
		.stage = { .sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
			   .stage = VK_SHADER_STAGE_COMPUTE_BIT, .module = e->modules[t],
			   .pName = "main", .pSpecializationInfo = &si },
		.layout = e->pipe_layout };
	VkPipeline p;
	VK_TRY(e->vk.vkCreateComputePipelines(e->dev, VK_NULL_HANDLE, 1, &ci, NULL, &p));
	e->pipelines_created++;
	e->pipes[t][e->n_pipes[t]].key = *key;
	e->pipes[t][e->n_pipes[t]].pipe = p;
	e->n_pipes[t]++;
	*ret = p;
fail:
	return rc;
}

/* Points the descriptor set at the current buffers and views. */
static void bind_buffers(struct eng *e)
{
	VkDescriptorBufferInfo bi[N_BINDINGS] = { { e->params.buf, 0, VK_WHOLE_SIZE } };
	VkWriteDescriptorSet w[N_BINDINGS];
	for (int i = 0; i < N_BINDINGS; i++) {
		w[i] = (VkWriteDescriptorSet){ .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
			.dstSet = e->set, .dstBinding = (uint32_t)i, .descriptorCount = 1,
			.descriptorType = eng_binding_type(i) };
		if (i > STATE_N_TABLES && i < BINDING_VIEWS) {
			w[i].pTexelBufferView = &e->lookup_view[i - 1 - STATE_N_TABLES];
			continue;
		}
		if (i == BINDING_MOMENT_TEX) {
			w[i].pTexelBufferView = &e->moment_view;
			continue;
		}
		if (i == BINDING_COLUMNS_TEX) {
			w[i].pTexelBufferView = &e->columns_view;
			continue;
		}
		if (i == BINDING_AERIAL_TEX) {
			w[i].pTexelBufferView = &e->aerial_view;
			continue;
		}
		if (i == BINDING_VIEWS)
			bi[i] = (VkDescriptorBufferInfo){ e->views.buf, 0, VK_WHOLE_SIZE };
		else if (i == BINDING_PACK)
			bi[i] = (VkDescriptorBufferInfo){ e->pack.buf, 0, VK_WHOLE_SIZE };
		else if (i == BINDING_COLUMNS)
			bi[i] = (VkDescriptorBufferInfo){ e->columns.buf, 0, VK_WHOLE_SIZE };
		else if (i == BINDING_ITERATE)
			bi[i] = (VkDescriptorBufferInfo){ e->ms_iterate.buf, 0, VK_WHOLE_SIZE };
		else if (i == BINDING_MOMENT)
			bi[i] = (VkDescriptorBufferInfo){ e->moment.buf, 0, VK_WHOLE_SIZE };
		else if (i > 0)
			bi[i] = (VkDescriptorBufferInfo){ e->table[i - 1].buf, 0, VK_WHOLE_SIZE };
		w[i].pBufferInfo = &bi[i];
	}
	e->vk.vkUpdateDescriptorSets(e->dev, N_BINDINGS, w, 0, NULL);
}

/* Texels of table t in s, every aerial volume of the plan counted. */
static uint64_t table_texels(const struct eng *e, const struct sky_state *s, int t)
{
	const struct state_table_quality *q = &s->quality.t[t];
	uint64_t n = (uint64_t)q->width * q->height * (t == STATE_AERIAL ? q->depth : 1);
	return t == STATE_AERIAL ? n * e->aplan.n_volumes : n;
}

/* Bytes of table t's float32 texels on the device. */
static VkDeviceSize float_bytes(const struct eng *e, const struct sky_state *s, int t)
{
	return table_texels(e, s, t) * 4 * sizeof(float);
}

/* Bytes of table t on the device before the panoramas: its float32
 * texels, then with storage=f16 its binary16 copy, which pack.comp writes
 * two texels at a time (an odd table gets one texel more). */
static VkDeviceSize table_device_bytes(const struct eng *e, const struct sky_state *s, int t)
{
	VkDeviceSize pairs = (table_texels(e, s, t) + 1) / 2;
	return float_bytes(e, s, t) + (s->quality.storage == STATE_F16 ? 16 * pairs : 0);
}

/* Bytes of table t on the device: the aerial buffer holds the plan's
 * panoramas after the volumes (float32, published as they are). */
static VkDeviceSize device_bytes(const struct eng *e, const struct sky_state *s, int t)
{
	VkDeviceSize panoramas = 16 * e->aplan.n_panoramas * aplan_panorama_texels(&e->aplan);
	return table_device_bytes(e, s, t) + (t == STATE_AERIAL ? panoramas : 0);
}

/* (Re)allocates table t: its device buffer (float32, then the published
 * copy for storage=f16), its host copy and, for a lookup, its texel view. */
static int table_new(struct eng *e, const struct sky_state *s, int t, char *err, size_t err_size)
{
	size_t bytes = table_texels(e, s, t) * state_texel_bytes(s->quality.storage);
	VkDeviceSize device = device_bytes(e, s, t);
	int rc = 0;

	if (t < N_LOOKUPS && e->lookup_view[t]) {
		e->vk.vkDestroyBufferView(e->dev, e->lookup_view[t], NULL);
		e->lookup_view[t] = VK_NULL_HANDLE;
	}
	if (t == STATE_AERIAL && e->aerial_view) {
		e->vk.vkDestroyBufferView(e->dev, e->aerial_view, NULL);
		e->aerial_view = VK_NULL_HANDLE;
	}
	eng_buffer_free(e, &e->table[t]);
	eng_buffer_free(e, &e->readback[t]);
	e->table_bytes[t] = e->device_bytes[t] = 0;
	rc = eng_buffer_new(e, device, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
				  VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
				  VK_BUFFER_USAGE_TRANSFER_DST_BIT,
			    VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT,
			    VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_CACHED_BIT,
			    &e->table[t], err, err_size);
	if (rc < 0)
		return rc;
	/* Mapped only where host-visible and cached (eng_buffer_new got what
	 * it preferred): reading it costs what reading host memory does. */
	e->direct[t] = e->table[t].map != NULL;
	e->published_offset[t] = s->quality.storage == STATE_F16 ? float_bytes(e, s, t) : 0;
	size_t panoramas = t == STATE_AERIAL ? (size_t)(device - table_device_bytes(e, s, t)) : 0;
	if (!e->direct[t])
		rc = eng_buffer_new(e, bytes + panoramas, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
				    VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT,
				    VK_MEMORY_PROPERTY_HOST_CACHED_BIT, &e->readback[t], err, err_size);
	if (rc < 0)
		return rc;
	if (t < N_LOOKUPS) {
		VkBufferViewCreateInfo vi = { .sType = VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO,
			.buffer = e->table[t].buf, .format = VK_FORMAT_R32G32B32A32_SFLOAT,
			.range = float_bytes(e, s, t) };
		VK_TRY(e->vk.vkCreateBufferView(e->dev, &vi, NULL, &e->lookup_view[t]));
	}
	if (t == STATE_AERIAL) {
		VkBufferViewCreateInfo vi = { .sType = VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO,
			.buffer = e->table[t].buf, .format = VK_FORMAT_R32G32B32A32_SFLOAT,
			.range = device / 16 * 16 };
		VK_TRY(e->vk.vkCreateBufferView(e->dev, &vi, NULL, &e->aerial_view));
	}
	memset(e->direct[t] ? (uint8_t *)e->table[t].map + e->published_offset[t] : e->readback[t].map,
	       0, bytes);
	e->table_bytes[t] = bytes;
	e->device_bytes[t] = device;
	if (t == STATE_AERIAL)
		e->panorama_offset = (size_t)table_device_bytes(e, s, t);
	e->rgb_scale_log2[t] = 0;
fail:
	return rc;
}

/* (Re)allocates the tables whose size or storage changed; returns the mask
 * of tables that must be recomputed because their contents were lost. */
static int ensure_tables(struct eng *e, const struct sky_state *s, uint32_t *ret_lost,
			 char *err, size_t err_size)
{
	uint32_t lost = 0;
	bool rebind = false;
	int rc = 0;

	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t bytes = table_texels(e, s, t) * state_texel_bytes(s->quality.storage);
		if (e->table[t].buf && e->table_bytes[t] == bytes && e->device_bytes[t] == device_bytes(e, s, t))
			continue;
		rc = table_new(e, s, t, err, err_size);
		if (rc < 0)
			return rc;
		lost |= STATE_BIT(t);
		rebind = true;
	}
	const struct state_table_quality *tq = &s->quality.t[STATE_TRANSMITTANCE];
	VkDeviceSize column_bytes = (VkDeviceSize)tq->width * tq->height * 4 * sizeof(float);
	if (!e->columns.buf || e->columns.bytes != column_bytes) {
		eng_vec4_buffer_free(e, &e->columns, &e->columns_view);
		e->columns_valid = false;
		rc = eng_vec4_buffer_new(e, column_bytes, &e->columns, &e->columns_view, err, err_size);
		if (rc < 0)
			return rc;
		rebind = true;
	}
	const struct state_table_quality *mq = &s->quality.t[STATE_MULTISCATTER];
	VkDeviceSize iterate_bytes = 2 * float_bytes(e, s, STATE_MULTISCATTER);
	if (!e->ms_iterate.buf || e->ms_iterate.bytes != iterate_bytes) {
		eng_buffer_free(e, &e->ms_iterate);
		rc = eng_buffer_new(e, iterate_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
						  VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
				VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, &e->ms_iterate, err, err_size);
		if (rc < 0)
			return rc;
		rebind = true;
	}
	VkDeviceSize moment_bytes = (VkDeviceSize)mq->width * mq->height * 4 * sizeof(float);
	if (!e->moment.buf || e->moment.bytes != moment_bytes) {
		eng_vec4_buffer_free(e, &e->moment, &e->moment_view);
		/* Its contents go with the multi-scattering table's, which is
		 * recomputed whenever its size (and so this one's) changes. */
		rc = eng_vec4_buffer_new(e, moment_bytes, &e->moment, &e->moment_view, err, err_size);
		if (rc < 0)
			return rc;
		rebind = true;
	}
	if (rebind)
		bind_buffers(e);
	*ret_lost = lost;
	return rc;
}

static void groups(const struct sky_state *s, int t, uint32_t *x, uint32_t *y)
{
	const struct state_table_quality *q = &s->quality.t[t];
	/* Multi-scattering and sky-view invocations compute several texels of a row. */
	uint32_t g = t == STATE_MULTISCATTER ? MS_SUN_GROUP : t == STATE_SKYVIEW ? SV_AZ_GROUP : 1;
	uint32_t w = (q->width + g - 1) / g;
	/* Workgroups are 8 x 8, but 4 x 16 for sky-view (skyview.comp). */
	uint32_t lx = 8, ly = 8;
	*x = (w + lx - 1) / lx;
	*y = (q->height + ly - 1) / ly;
}

/* Records one pass: its dispatch between two timestamps (queries 2 pass and
 * 2 pass + 1), then a barrier so that the next pass reads what it wrote;
 * with then_gz > 0, a second dispatch of then over (gx, then_gy, then_gz) that
 * reads the first's output (the views' resampling), and its barrier; with
 * pack_groups > 0, also the pack pass of its table (pack.comp), which
 * needs that barrier and which no later pass reads (nor waits for). */
static void record_pass(struct eng *e, int pass, VkPipeline pipe, uint32_t gx, uint32_t gy,
			uint32_t gz, uint32_t then_gy, VkPipeline then, uint32_t then_gz, VkPipeline pack,
			uint32_t pack_groups)
{
	const VkMemoryBarrier compute_to_compute = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT, .dstAccessMask = VK_ACCESS_SHADER_READ_BIT };

	if (e->timestamps)
		e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, e->queries,
					  2 * (uint32_t)pass);
	e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipe);
	e->vk.vkCmdDispatch(e->cmd, gx, gy, gz);
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
				   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &compute_to_compute, 0,
				   NULL, 0, NULL);
	if (then_gz) {
		e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, then);
		e->vk.vkCmdDispatch(e->cmd, gx, then_gy, then_gz);
		e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
					   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &compute_to_compute,
					   0, NULL, 0, NULL);
	}
	if (pack_groups) {
		e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pack);
		e->vk.vkCmdDispatch(e->cmd, pack_groups, 1, 1);
	}
	if (e->timestamps)
		e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, e->queries,
					  2 * (uint32_t)pass + 1);
}

/* Records the steps of the iteration of psi_ms after the multi-scattering
 * pass: each step writes the next table into the scratch buffer, which is
 * then copied over the table (later passes and the next step read it
 * through the lookup view). One pair of timestamps spans all steps. With
 * storage=f16 the table's range is cleared before the last step, which
 * records the range of what it stores: the table's. */
static void record_iteration(struct eng *e, const struct sky_state *s, const VkPipeline pipes[2],
			     uint32_t steps, VkPipeline pack, uint32_t pack_groups)
{
	const VkMemoryBarrier to_copy = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_SHADER_READ_BIT,
		.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT };
	const VkMemoryBarrier to_read = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
		.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT };
	uint32_t gx, gy;

	groups(s, STATE_MULTISCATTER, &gx, &gy);
	if (e->timestamps)
		e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, e->queries,
					  2 * PASS_MSITERATE);
	for (uint32_t i = 0; i < steps; i++) {
		if (i == steps - 1 && s->quality.storage == STATE_F16) {
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
		e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipes[i > 0]);
		e->vk.vkCmdDispatch(e->cmd, gx, gy, 1);
		e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
					   VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &to_copy, 0, NULL, 0, NULL);
		VkBufferCopy c = { 0, 0, float_bytes(e, s, STATE_MULTISCATTER) };
		e->vk.vkCmdCopyBuffer(e->cmd, e->ms_iterate.buf, e->table[STATE_MULTISCATTER].buf, 1, &c);
		e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
					   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &to_read, 0, NULL, 0,
					   NULL);
	}
	if (pack_groups) {
		e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pack);
		e->vk.vkCmdDispatch(e->cmd, pack_groups, 1, 1);
	}
	if (e->timestamps)
		e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, e->queries,
					  2 * PASS_MSITERATE + 1);
}

/* Whether the device can hold and dispatch every table of s: 0, or -EINVAL
 * with the table and the limit in err. */
static int check_limits(const struct eng *e, const struct sky_state *s, char *err, size_t err_size)
{
	for (int t = 0; t < STATE_N_TABLES; t++) {
		const struct state_table_quality *q = &s->quality.t[t];
		uint32_t gx, gy;
		groups(s, t, &gx, &gy);
		if (t < N_LOOKUPS && (uint64_t)q->width * q->height > e->limits.maxTexelBufferElements) {
			eng_set_err(err, err_size, "%s_width: %ux%u texels exceed the device's %u for a lookup table",
				state_table_names[t], q->width, q->height,
				e->limits.maxTexelBufferElements);
			return -EINVAL;
		}
		if (gx > e->limits.maxComputeWorkGroupCount[0] ||
		    gy > e->limits.maxComputeWorkGroupCount[1] || q->width == 0 || q->height == 0) {
			eng_set_err(err, err_size, "%s_width: %ux%u is beyond the device's limits",
				state_table_names[t], q->width, q->height);
			return -EINVAL;
		}
		/* The device holds float32 texels, and the binary16 copy too. */
		uint64_t device = device_bytes(e, s, t);
		if (t == STATE_AERIAL && device / 16 > e->limits.maxTexelBufferElements) {
			eng_set_err(err, err_size, "aerial_width: %ux%ux%u for %u volumes exceeds the device's %u texels for a lookup",
				q->width, q->height, q->depth, 1 + s->n_views, e->limits.maxTexelBufferElements);
			return -EINVAL;
		}
		if (device > e->limits.maxStorageBufferRange) {
			eng_set_err(err, err_size, "%s_width: %ux%u needs %llu bytes of device buffer, above the device's %u",
				state_table_names[t], q->width, q->height, (unsigned long long)device,
				e->limits.maxStorageBufferRange);
			return -EINVAL;
		}
	}
	return 0;
}

/* What one computation runs: the pipelines of the tables in mask, the
 * column pass's when the kept columns do not fit (run_columns, key), the
 * steps of the iteration of psi_ms, and for storage=f16 the pack pass over
 * pack_groups workgroups (0: none). */
struct plan {
	uint32_t mask;
	VkPipeline pipes[STATE_N_TABLES];
	VkPipeline column_pipe;
	bool run_columns;
	struct column_key key;
	VkPipeline iterate_pipes[2];
	uint32_t iterations;
	VkPipeline pack_pipe;
	uint32_t pack_groups;
	uint32_t aerial_march, aerial_resample;	/* eng_fill_views' jobs */
	VkPipeline resample_pipe;
};

/* The pack pass's plan: its pipeline for the tables of mask it packs (all
 * but transmittance, which packs itself) and its workgroups, each
 * invocation of 64 packing up to 16 texels of the largest of them. */
static int plan_pack(struct eng *e, const struct sky_state *s, struct plan *pl, char *err,
		     size_t err_size)
{
	struct spec k = { { 0 } };
	uint64_t most = 0;
	k.v[SPEC_PACK_MASK] = (int32_t)(pl->mask & ~STATE_BIT(STATE_TRANSMITTANCE));
	if (!k.v[SPEC_PACK_MASK])
		return 0;
	for (int t = 0; t < STATE_N_TABLES; t++)
		if (k.v[SPEC_PACK_MASK] & STATE_BIT(t) && table_texels(e, s, t) > most)
			most = table_texels(e, s, t);
	uint64_t groups = (most + 64 * 16 - 1) / (64 * 16);
	pl->pack_groups = groups > e->limits.maxComputeWorkGroupCount[0]
				  ? e->limits.maxComputeWorkGroupCount[0] : (uint32_t)groups;
	return get_pipeline(e, PASS_PACK, &k, &pl->pack_pipe, err, err_size);
}

/* Fills params and plan for s and mask, creating the pipelines it lacks. */
static int make_plan(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		     uint32_t mask, struct gpu_params *params, struct plan *ret, char *err,
		     size_t err_size)
{
	struct spec base;
	int rc;

	memset(ret, 0, sizeof(*ret));
	ret->mask = mask;
	eng_fill_params(e, s, lights, params, &base);
	eng_fill_views(s, &e->aplan, e->panorama_offset / 16, e->views.map, &ret->aerial_march,
		       &ret->aerial_resample);
	if ((mask & STATE_BIT(STATE_AERIAL)) && ret->aerial_resample) {
		struct spec k = eng_pass_spec(&base, s, STATE_AERIAL);
		rc = get_pipeline(e, PASS_RESAMPLE, &k, &ret->resample_pipe, err, err_size);
		if (rc < 0)
			return rc;
	}
	for (int t = 0; t < STATE_N_TABLES; t++)
		if (mask & STATE_BIT(t)) {
			struct spec k = eng_pass_spec(&base, s, t);
			rc = get_pipeline(e, t, &k, &ret->pipes[t], err, err_size);
			if (rc < 0)
				return rc;
		}
	/* The iteration of psi_ms: its first step recovers L2 from the table,
	 * the later ones read it back (SPEC_ITER_FIRST). */
	ret->iterations = (mask & STATE_BIT(STATE_MULTISCATTER)) ? state_multiscatter_iterations(s) : 0;
	for (int i = 0; i < 2 && ret->iterations > 0; i++) {
		struct spec k = eng_pass_spec(&base, s, STATE_MULTISCATTER);
		k.v[SPEC_ITER_FIRST] = i == 0;
		rc = get_pipeline(e, PASS_MSITERATE, &k, &ret->iterate_pipes[i], err, err_size);
		if (rc < 0)
			return rc;
	}
	/* The column densities are recomputed only when what they depend on
	 * changed; the same inputs give the same bits, so a table made from
	 * kept columns is the one a fresh engine makes. */
	struct spec ck = eng_column_spec(&base, s);
	eng_column_key(params, &ck, &ret->key);
	ret->run_columns = (mask & STATE_BIT(STATE_TRANSMITTANCE)) &&
			   (!e->columns_valid || memcmp(&ret->key, &e->column_key, sizeof(ret->key)));
	if (ret->run_columns && (rc = get_pipeline(e, PASS_COLUMNS, &ck, &ret->column_pipe, err, err_size)) < 0)
		return rc;
	return s->quality.storage == STATE_F16 && mask ? plan_pack(e, s, ret, err, err_size) : 0;
}

/* The rows of aerial_width invocations the march dispatch needs: the
 * volume's, or a panorama's columns where they are more. */
static uint32_t aerial_march_rows(const struct eng *e, const struct sky_state *s)
{
	const struct state_table_quality *q = &s->quality.t[STATE_AERIAL];
	uint32_t rows = (e->aplan.width * e->aplan.height + q->width - 1) / q->width;
	return e->aplan.n_panoramas && rows > q->height ? rows : q->height;
}

/* Records the plan's passes into e->cmd, then the copies of its tables to
 * host memory. */
static int record_plan(struct eng *e, const struct sky_state *s, const struct plan *pl, char *err,
		       size_t err_size)
{
	int rc = 0;
	VkCommandBufferBeginInfo bi = { .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
		.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT };
	VK_TRY(e->vk.vkBeginCommandBuffer(e->cmd, &bi));
	if (e->timestamps)
		e->vk.vkCmdResetQueryPool(e->cmd, e->queries, 0, 2 * N_PASSES);
	e->vk.vkCmdBindDescriptorSets(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, e->pipe_layout, 0, 1,
				      &e->set, 0, NULL);
	for (int t = 0; t < STATE_N_TABLES; t++) {
		if (!(pl->mask & STATE_BIT(t)))
			continue;
		uint32_t gx, gy;
		groups(s, t, &gx, &gy);
		if (t == STATE_TRANSMITTANCE && pl->run_columns)
			record_pass(e, PASS_COLUMNS, pl->column_pipe, gx, gy, 1, 0, VK_NULL_HANDLE, 0,
				    VK_NULL_HANDLE, 0);
		/* Every aerial march in one dispatch, z the job, then every
		 * resampled volume in another. The float16 copies follow the
		 * last pass, in its time. */
		bool last = !(pl->mask >> (t + 1)), iterate = t == STATE_MULTISCATTER && pl->iterations > 0;
		bool aerial = t == STATE_AERIAL;
		uint32_t pack = last ? pl->pack_groups : 0;
		uint32_t march_gy = aerial ? (aerial_march_rows(e, s) + 7) / 8 : gy;
		record_pass(e, t, pl->pipes[t], gx, march_gy, aerial ? pl->aerial_march : 1, gy,
			    pl->resample_pipe, aerial ? pl->aerial_resample : 0, pl->pack_pipe,
			    iterate ? 0 : pack);
		if (iterate)
			record_iteration(e, s, pl->iterate_pipes, pl->iterations, pl->pack_pipe, pack);
	}
	VkMemoryBarrier to_copy = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT, .dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT };
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
				   VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &to_copy, 0, NULL, 0, NULL);
	/* The published copy: the float32 texels, or the binary16 ones after
	 * them; none where the host reads the device's memory. */
	for (int t = 0; t < STATE_N_TABLES; t++)
		if ((pl->mask & STATE_BIT(t)) && !e->direct[t]) {
			/* The panoramas that views read; scratch ones stay. */
			VkDeviceSize published = aplan_published_bytes(&e->aplan);
			VkBufferCopy c[2] = { { s->quality.storage == STATE_F16 ? float_bytes(e, s, t) : 0, 0,
						e->table_bytes[t] },
					      { e->panorama_offset, e->table_bytes[t], published } };
			bool panoramas = t == STATE_AERIAL && published;
			e->vk.vkCmdCopyBuffer(e->cmd, e->table[t].buf, e->readback[t].buf, panoramas ? 2 : 1, c);
		}
	/* The host reads the copies and the pack pass's scales. */
	VkMemoryBarrier to_host = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT,
		.dstAccessMask = VK_ACCESS_HOST_READ_BIT };
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
				   VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, NULL, 0, NULL);
	VK_TRY(e->vk.vkEndCommandBuffer(e->cmd));
fail:
	return rc;
}

int eng_submit(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
	       uint32_t mask, char *err, size_t err_size)
{
	struct gpu_params params;
	struct state_lights own;
	struct plan pl;
	uint32_t lost = 0;
	int rc = 0;

	pthread_mutex_lock(&e->lock);
	bool busy = e->pending || e->finished;
	pthread_mutex_unlock(&e->lock);
	if (busy) {
		eng_set_err(err, err_size, "a computation is in flight");
		return -EBUSY;
	}
	if (!lights) {
		state_lights_of(s, &own);
		lights = &own;
	}
	/* The plan of this computation: the buffers' sizes and the jobs. */
	aplan_make_lit(s, lights, e->share_views, &e->aplan);
	rc = check_limits(e, s, err, err_size);
	if (rc == 0)
		rc = ensure_tables(e, s, &lost, err, err_size);
	if (rc < 0)
		return rc;
	/* Exactly mask: a table the caller did not ask for is neither computed
	 * nor forced, so demand decides the cost. Only a dependency of mask
	 * whose buffer was reallocated must come along. */
	mask |= lost & state_closure(mask);
	rc = make_plan(e, s, lights, mask, &params, &pl, err, err_size);
	if (rc < 0)
		return rc;
	memcpy(e->params.map, &params, sizeof(params));
	if (s->quality.storage == STATE_F16) {
		struct gpu_pack pack;
		memset(&pack, 0, sizeof(pack));
		for (int t = STATE_MULTISCATTER; t < STATE_N_TABLES; t++)
			pack.texels[t] = (mask & STATE_BIT(t)) ? (uint32_t)table_texels(e, s, t) : 0;
		memcpy(e->pack.map, &pack, sizeof(pack));
	}
	rc = record_plan(e, s, &pl, err, err_size);
	if (rc < 0)
		return rc;
	VK_TRY(e->vk.vkResetFences(e->dev, 1, &e->fence));
	VkSubmitInfo si = { .sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1,
		.pCommandBuffers = &e->cmd };
	clock_gettime(CLOCK_MONOTONIC, &e->submit_time);
	VK_TRY(e->vk.vkQueueSubmit(e->queue, 1, &si, e->fence));

	if (pl.run_columns) {
		/* Invalidated again if the computation fails (eng_complete). */
		e->column_key = pl.key;
		e->columns_valid = true;
	}
	e->columns_in_flight = pl.run_columns;
	e->iterations_in_flight = pl.iterations;
	e->pack_in_flight = s->quality.storage == STATE_F16;
	pthread_mutex_lock(&e->lock);
	e->in_flight_mask = mask;
	e->pending = true;
	e->finished = false;
	pthread_cond_signal(&e->cond);
	pthread_mutex_unlock(&e->lock);
	return 0;
fail:
	return rc;
}

int eng_complete(struct eng *e, struct eng_timing *ret, char *err, size_t err_size)
{
	struct timespec now;
	uint64_t count;
	int rc = 0;

	pthread_mutex_lock(&e->lock);
	bool done = e->finished;
	VkResult wr = e->wait_result;
	uint32_t mask = e->in_flight_mask;
	pthread_mutex_unlock(&e->lock);
	if (!done)
		return -EAGAIN;
	clock_gettime(CLOCK_MONOTONIC, &now);
	while (read(e->event_fd, &count, sizeof(count)) == sizeof(count))
		;

	struct eng_timing t = { .computed = mask, .total_ms = elapsed_ms(&e->submit_time, &now),
		.columns = e->columns_in_flight };
	pthread_mutex_lock(&e->lock);
	e->finished = false;
	pthread_mutex_unlock(&e->lock);
	if (wr != VK_SUCCESS)
		e->columns_valid = false;
	VK_TRY(wr);
	for (int i = 0; i < STATE_N_TABLES; i++) {
		if (!(mask & STATE_BIT(i)))
			continue;
		VkMappedMemoryRange r = { .sType = VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE,
			.memory = e->direct[i] ? e->table[i].mem : e->readback[i].mem, .size = VK_WHOLE_SIZE };
		VK_TRY(e->vk.vkInvalidateMappedMemoryRanges(e->dev, 1, &r));
		e->rgb_scale_log2[i] = !e->pack_in_flight ? 0
				       : i == STATE_TRANSMITTANCE ? SKY_F16_TRANSMITTANCE_LOG2
				       : ((const struct gpu_pack *)e->pack.map)->scale_log2[i];
	}
	if (e->timestamps) {
		uint64_t ts[2 * STATE_N_TABLES];
		for (int i = 0; i < STATE_N_TABLES; i++) {
			if (!(mask & STATE_BIT(i)))
				continue;
			VK_TRY(e->vk.vkGetQueryPoolResults(e->dev, e->queries, 2 * i, 2, sizeof(uint64_t) * 2,
							   &ts[2 * i], sizeof(uint64_t),
							   VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
			t.table_ms[i] = (double)(ts[2 * i + 1] - ts[2 * i]) * e->timestamp_period_ns * 1e-6;
		}
		if (t.columns) {
			VK_TRY(e->vk.vkGetQueryPoolResults(e->dev, e->queries, 2 * PASS_COLUMNS, 2,
							   sizeof(uint64_t) * 2, ts, sizeof(uint64_t),
							   VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
			t.columns_ms = (double)(ts[1] - ts[0]) * e->timestamp_period_ns * 1e-6;
			t.table_ms[STATE_TRANSMITTANCE] += t.columns_ms;
		}
		if (e->iterations_in_flight) {
			VK_TRY(e->vk.vkGetQueryPoolResults(e->dev, e->queries, 2 * PASS_MSITERATE, 2,
							   sizeof(uint64_t) * 2, ts, sizeof(uint64_t),
							   VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
			t.table_ms[STATE_MULTISCATTER] += (double)(ts[1] - ts[0]) * e->timestamp_period_ns * 1e-6;
		}
	}
	*ret = t;
	return 0;
fail:
	return rc;
}

void eng_set_view_sharing(struct eng *e, int share)
{
	e->share_views = share != 0;
}

int eng_wait(struct eng *e, struct eng_timing *ret, char *err, size_t err_size)
{
	struct pollfd p = { .fd = e->event_fd, .events = POLLIN };
	for (;;) {
		int rc = eng_complete(e, ret, err, err_size);
		if (rc != -EAGAIN)
			return rc;
		pthread_mutex_lock(&e->lock);
		bool idle = !e->pending && !e->finished;
		pthread_mutex_unlock(&e->lock);
		if (idle) {
			eng_set_err(err, err_size, "nothing was submitted");
			return -EINVAL;
		}
		if (poll(&p, 1, -1) < 0 && errno != EINTR)
			return -errno;
	}
}

int eng_compute(struct eng *e, const struct sky_state *s, uint32_t mask, struct eng_timing *ret,
		char *err, size_t err_size)
{
	int rc = eng_submit(e, s, NULL, mask, err, err_size);
	return rc < 0 ? rc : eng_wait(e, ret, err, err_size);
}
