/* eng_tables.c - the tables' buffers on the device, their host copies, the
 * engine's internal buffers, and the one descriptor set that points at
 * them. */
#include "eng_internal.h"

#include <string.h>

/* Points the descriptor set at the current buffers and views. */
static void bind_buffers(struct eng *e)
{
	VkDescriptorBufferInfo bi[N_BINDINGS] = { { e->params.buf, 0, VK_WHOLE_SIZE } };
	VkDescriptorImageInfo ii[N_LOOKUPS];
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
		if (i == BINDING_CLOUD_TEX || i == BINDING_SHADOW_TEX) {
			w[i].pTexelBufferView = i == BINDING_CLOUD_TEX ? &e->ct.cloud_view : &e->ct.shadow_view;
			continue;
		}
		if (i == BINDING_TRANSMITTANCE_IMG || i == BINDING_MULTISCATTER_IMG) {
			const struct lookup_image *li = &e->lookup_image[i - BINDING_TRANSMITTANCE_IMG];
			ii[i - BINDING_TRANSMITTANCE_IMG] = (VkDescriptorImageInfo){ e->sampler, li->view,
				VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL };
			w[i].pImageInfo = &ii[i - BINDING_TRANSMITTANCE_IMG];
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
		else if (i == BINDING_CLOUDS)
			bi[i] = (VkDescriptorBufferInfo){ e->clouds.buf, 0, VK_WHOLE_SIZE };
		else if (i == BINDING_CLOUD)
			bi[i] = (VkDescriptorBufferInfo){ e->ct.cloud.buf, 0, VK_WHOLE_SIZE };
		else if (i == BINDING_SHADOW)
			bi[i] = (VkDescriptorBufferInfo){ e->ct.shadow.buf, 0, VK_WHOLE_SIZE };
		else if (i == BINDING_TERRAIN)
			bi[i] = (VkDescriptorBufferInfo){ e->terrain.buf, 0, VK_WHOLE_SIZE };
		else if (i == BINDING_SV_LIGHT)
			bi[i] = (VkDescriptorBufferInfo){ e->sv_light.buf, 0, VK_WHOLE_SIZE };
		else if (i == BINDING_MULTISCATTER_UBO)
			bi[i] = (VkDescriptorBufferInfo){ e->table[STATE_MULTISCATTER].buf, 0, e->ms_uniform_bytes };
		else if (i > 0)
			bi[i] = (VkDescriptorBufferInfo){ e->table[i - 1].buf, 0, VK_WHOLE_SIZE };
		w[i].pBufferInfo = &bi[i];
	}
	e->vk.vkUpdateDescriptorSets(e->dev, N_BINDINGS, w, 0, NULL);
}

uint64_t eng_table_texels(const struct eng *e, const struct sky_state *s, int t)
{
	const struct state_table_quality *q = &s->quality.t[t];
	uint64_t n = (uint64_t)q->width * q->height * (t == STATE_AERIAL ? q->depth : 1);
	return t == STATE_AERIAL ? n * e->aplan.n_volumes : n;
}

VkDeviceSize eng_float_bytes(const struct eng *e, const struct sky_state *s, int t)
{
	return eng_table_texels(e, s, t) * 4 * sizeof(float);
}

/* Bytes of table t on the device before the panoramas: its float32
 * texels, then with storage=f16 its binary16 copy, which pack.comp writes
 * two texels at a time (an odd table gets one texel more). */
static VkDeviceSize table_device_bytes(const struct eng *e, const struct sky_state *s, int t)
{
	VkDeviceSize pairs = (eng_table_texels(e, s, t) + 1) / 2;
	return eng_float_bytes(e, s, t) + (s->quality.storage == STATE_F16 ? 16 * pairs : 0);
}

/* Bytes of table t on the device: the aerial buffer holds the plan's
 * panoramas after the volumes (float32, published as they are). */
static VkDeviceSize device_bytes(const struct eng *e, const struct sky_state *s, int t)
{
	VkDeviceSize panoramas = 16 * e->aplan.n_panoramas * aplan_panorama_texels(&e->aplan);
	return table_device_bytes(e, s, t) + (t == STATE_AERIAL ? panoramas : 0);
}

/* (Re)allocates table t: its device buffer (float32, then the published
 * copy for storage=f16), its host copy (zeroed) and, for a lookup, its
 * texel view. */
static int table_new(struct eng *e, const struct sky_state *s, int t, char *err, size_t err_size)
{
	size_t bytes = eng_table_texels(e, s, t) * state_texel_bytes(s->quality.storage);
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
	rc = eng_buffer_new(e, device, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT |
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
	e->published_offset[t] = s->quality.storage == STATE_F16 ? eng_float_bytes(e, s, t) : 0;
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
			.range = eng_float_bytes(e, s, t) };
		VK_TRY(e->vk.vkCreateBufferView(e->dev, &vi, NULL, &e->lookup_view[t]));
		if (t == STATE_MULTISCATTER)
			e->ms_uniform_bytes = vi.range < 16 * SKY_MS_UNIFORM_TEXELS ? vi.range
										  : 16 * SKY_MS_UNIFORM_TEXELS;
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
	e->host_fresh[t] = true;
	if (t == STATE_AERIAL)
		e->panorama_offset = (size_t)table_device_bytes(e, s, t);
	e->rgb_scale_log2[t] = 0;
fail:
	return rc;
}

static void image_free(struct eng *e, struct lookup_image *li)
{
	if (li->view)
		e->vk.vkDestroyImageView(e->dev, li->view, NULL);
	if (li->img)
		e->vk.vkDestroyImage(e->dev, li->img, NULL);
	if (li->mem)
		e->vk.vkFreeMemory(e->dev, li->mem, NULL);
	memset(li, 0, sizeof(*li));
}

/* Lookup table t as a width x height float32 RGBA image that copies fill
 * and shaders sample. */
static int image_new(struct eng *e, uint32_t width, uint32_t height, struct lookup_image *li,
		     char *err, size_t err_size)
{
	VkImageCreateInfo ci = { .sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO, .imageType = VK_IMAGE_TYPE_2D,
		.format = VK_FORMAT_R32G32B32A32_SFLOAT, .extent = { width, height, 1 }, .mipLevels = 1,
		.arrayLayers = 1, .samples = VK_SAMPLE_COUNT_1_BIT, .tiling = VK_IMAGE_TILING_OPTIMAL,
		.usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
		.sharingMode = VK_SHARING_MODE_EXCLUSIVE, .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED };
	VkMemoryRequirements req;
	int rc = 0;

	VK_TRY(e->vk.vkCreateImage(e->dev, &ci, NULL, &li->img));
	e->vk.vkGetImageMemoryRequirements(e->dev, li->img, &req);
	int type = vkcheck_find_memory(&e->mem_props, req.memoryTypeBits, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
	if (type < 0) {
		eng_set_err(err, err_size, "no Vulkan memory type for a lookup image");
		return -ENOMEM;
	}
	VkMemoryAllocateInfo ai = { .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
		.allocationSize = req.size, .memoryTypeIndex = (uint32_t)type };
	VK_TRY(e->vk.vkAllocateMemory(e->dev, &ai, NULL, &li->mem));
	VK_TRY(e->vk.vkBindImageMemory(e->dev, li->img, li->mem, 0));
	VkImageViewCreateInfo vi = { .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO, .image = li->img,
		.viewType = VK_IMAGE_VIEW_TYPE_2D, .format = VK_FORMAT_R32G32B32A32_SFLOAT,
		.subresourceRange = { VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1 } };
	VK_TRY(e->vk.vkCreateImageView(e->dev, &vi, NULL, &li->view));
	li->width = width;
	li->height = height;
fail:
	return rc;
}

/* The lookup images at the size of the lookup tables of s. */
static int ensure_images(struct eng *e, const struct sky_state *s, bool *rebind, char *err,
			 size_t err_size)
{
	for (int t = 0; t < N_LOOKUPS; t++) {
		struct lookup_image *li = &e->lookup_image[t];
		const struct state_table_quality *q = &s->quality.t[t];
		if (li->img && li->width == q->width && li->height == q->height)
			continue;
		image_free(e, li);
		int rc = image_new(e, q->width, q->height, li, err, err_size);
		if (rc < 0) {
			image_free(e, li);
			return rc;
		}
		e->images_valid = false;
		e->images_new = true;
		*rebind = true;
	}
	return 0;
}

void eng_record_image_layouts(struct eng *e)
{
	VkImageMemoryBarrier b[N_LOOKUPS];

	if (!e->images_new)
		return;
	for (int t = 0; t < N_LOOKUPS; t++)
		b[t] = (VkImageMemoryBarrier){ .sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER,
			.dstAccessMask = VK_ACCESS_SHADER_READ_BIT, .oldLayout = VK_IMAGE_LAYOUT_UNDEFINED,
			.newLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
			.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED, .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
			.image = e->lookup_image[t].img, .subresourceRange = { VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1 } };
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
				   0, 0, NULL, 0, NULL, N_LOOKUPS, b);
	e->images_new = false;
}

/* The internal buffers sized by s: the column densities, the iteration's
 * scratch and the shape; *rebind when one was reallocated. */
static int ensure_internal(struct eng *e, const struct sky_state *s, bool *rebind, char *err,
			   size_t err_size)
{
	const struct state_table_quality *tq = &s->quality.t[STATE_TRANSMITTANCE];
	const struct state_table_quality *mq = &s->quality.t[STATE_MULTISCATTER];
	VkDeviceSize column_bytes = (VkDeviceSize)tq->width * tq->height * 4 * sizeof(float);
	VkDeviceSize iterate_bytes = 2 * eng_float_bytes(e, s, STATE_MULTISCATTER);
	VkDeviceSize moment_bytes = (VkDeviceSize)mq->width * mq->height * 4 * sizeof(float);
	int rc = 0;

	if (!e->columns.buf || e->columns.bytes != column_bytes) {
		eng_vec4_buffer_free(e, &e->columns, &e->columns_view);
		e->columns_valid = false;
		rc = eng_vec4_buffer_new(e, column_bytes, &e->columns, &e->columns_view, err, err_size);
		if (rc < 0)
			return rc;
		*rebind = true;
	}
	if (!e->ms_iterate.buf || e->ms_iterate.bytes != iterate_bytes) {
		eng_buffer_free(e, &e->ms_iterate);
		rc = eng_buffer_new(e, iterate_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
						  VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
				VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, &e->ms_iterate, err, err_size);
		if (rc < 0)
			return rc;
		*rebind = true;
	}
	if (!e->moment.buf || e->moment.bytes != moment_bytes) {
		eng_vec4_buffer_free(e, &e->moment, &e->moment_view);
		/* Its contents go with the multi-scattering table's, which is
		 * recomputed whenever its size (and so this one's) changes. */
		rc = eng_vec4_buffer_new(e, moment_bytes, &e->moment, &e->moment_view, err, err_size);
		if (rc < 0)
			return rc;
		*rebind = true;
	}
	return rc;
}

int eng_ensure_tables(struct eng *e, const struct sky_state *s, uint32_t *ret_lost, char *err,
		      size_t err_size)
{
	uint32_t lost = 0;
	bool rebind = false;
	int rc = 0;

	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t bytes = eng_table_texels(e, s, t) * state_texel_bytes(s->quality.storage);
		if (e->table[t].buf && e->table_bytes[t] == bytes && e->device_bytes[t] == device_bytes(e, s, t))
			continue;
		rc = table_new(e, s, t, err, err_size);
		if (rc < 0)
			return rc;
		lost |= STATE_BIT(t);
		rebind = true;
	}
	rc = ensure_internal(e, s, &rebind, err, err_size);
	if (rc == 0)
		rc = ensure_images(e, s, &rebind, err, err_size);
	if (rc == 0)
		rc = eng_ensure_clouds(e, s, &rebind, err, err_size);
	if (rc < 0)
		return rc;
	if (rebind || e->clouds_rebind)
		bind_buffers(e);
	e->clouds_rebind = false;
	*ret_lost = lost;
	return rc;
}

int eng_check_limits(const struct eng *e, const struct sky_state *s, char *err, size_t err_size)
{
	for (int t = 0; t < STATE_N_TABLES; t++) {
		const struct state_table_quality *q = &s->quality.t[t];
		if (t < N_LOOKUPS && (uint64_t)q->width * q->height > e->limits.maxTexelBufferElements) {
			eng_set_err(err, err_size, "%s_width: %ux%u texels exceed the device's %u for a lookup table",
				state_table_names[t], q->width, q->height,
				e->limits.maxTexelBufferElements);
			return -EINVAL;
		}
		if (q->width == 0 || q->height == 0) {
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

void eng_free_tables(struct eng *e)
{
	for (int i = 0; i < N_LOOKUPS; i++)
		if (e->lookup_view[i])
			e->vk.vkDestroyBufferView(e->dev, e->lookup_view[i], NULL);
	if (e->aerial_view)
		e->vk.vkDestroyBufferView(e->dev, e->aerial_view, NULL);
	for (int t = 0; t < STATE_N_TABLES; t++) {
		eng_buffer_free(e, &e->table[t]);
		eng_buffer_free(e, &e->readback[t]);
	}
	eng_vec4_buffer_free(e, &e->columns, &e->columns_view);
	eng_buffer_free(e, &e->ms_iterate);
	eng_vec4_buffer_free(e, &e->moment, &e->moment_view);
	for (int t = 0; t < N_LOOKUPS; t++)
		image_free(e, &e->lookup_image[t]);
	eng_free_clouds(e);
}
