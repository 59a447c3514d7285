/* eng_host.c - where a computation's published tables go: host memory the
 * device writes itself (the publisher's slot, imported with
 * VK_EXT_external_memory_host), or the engine's own host copies. */
#include "eng_internal.h"

#include <string.h>

/* The region imported at base; with base NULL, a free entry. */
static struct host_region *find_region(struct eng *e, const void *base)
{
	for (size_t i = 0; i < sizeof(e->regions) / sizeof(e->regions[0]); i++)
		if (e->regions[i].base == base)
			return &e->regions[i];
	return NULL;
}

static void region_free(struct eng *e, struct host_region *r)
{
	if (r->buf)
		e->vk.vkDestroyBuffer(e->dev, r->buf, NULL);
	if (r->mem)
		e->vk.vkFreeMemory(e->dev, r->mem, NULL);
	memset(r, 0, sizeof(*r));
}

/* The buffer over the imported memory, which only copies write. */
static int import_buffer(struct eng *e, struct host_region *r, char *err, size_t err_size)
{
	const VkExternalMemoryHandleTypeFlagBits type = VK_EXTERNAL_MEMORY_HANDLE_TYPE_HOST_ALLOCATION_BIT_EXT;
	VkMemoryHostPointerPropertiesEXT hp = { .sType = VK_STRUCTURE_TYPE_MEMORY_HOST_POINTER_PROPERTIES_EXT };
	VkExternalMemoryBufferCreateInfo ext = { .sType = VK_STRUCTURE_TYPE_EXTERNAL_MEMORY_BUFFER_CREATE_INFO,
		.handleTypes = type };
	VkBufferCreateInfo bi = { .sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO, .pNext = &ext,
		.size = r->bytes, .usage = VK_BUFFER_USAGE_TRANSFER_DST_BIT,
		.sharingMode = VK_SHARING_MODE_EXCLUSIVE };
	VkMemoryRequirements req;
	int rc = 0;

	VK_TRY(e->get_host_pointer_props(e->dev, type, r->base, &hp));
	VK_TRY(e->vk.vkCreateBuffer(e->dev, &bi, NULL, &r->buf));
	e->vk.vkGetBufferMemoryRequirements(e->dev, r->buf, &req);
	/* Coherent: the publisher reads the tables through its own mapping,
	 * which no vkInvalidateMappedMemoryRanges could reach. */
	int mt = vkcheck_find_memory(&e->mem_props, req.memoryTypeBits & hp.memoryTypeBits,
				     VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
				     0);
	if (mt < 0 || req.size > r->bytes) {
		eng_set_err(err, err_size, "no host-coherent memory type of the device can import the region");
		return -EOPNOTSUPP;
	}
	VkImportMemoryHostPointerInfoEXT imp = { .sType = VK_STRUCTURE_TYPE_IMPORT_MEMORY_HOST_POINTER_INFO_EXT,
		.handleType = type, .pHostPointer = r->base };
	VkMemoryAllocateInfo ai = { .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO, .pNext = &imp,
		.allocationSize = r->bytes, .memoryTypeIndex = (uint32_t)mt };
	VK_TRY(e->vk.vkAllocateMemory(e->dev, &ai, NULL, &r->mem));
	VK_TRY(e->vk.vkBindBufferMemory(e->dev, r->buf, r->mem, 0));
fail:
	return rc;
}

int eng_host_import(struct eng *e, void *base, size_t bytes, char *err, size_t err_size)
{
	struct host_region *r = base ? find_region(e, base) : NULL;
	VkDeviceSize a = e->import_alignment;

	if (r)
		return 0;
	if (!e->host_import) {
		eng_set_err(err, err_size, "the device lacks VK_EXT_external_memory_host");
		return -EOPNOTSUPP;
	}
	if (!base || !bytes || (uintptr_t)base % a || bytes % a) {
		eng_set_err(err, err_size, "the region (%zu bytes at %p) is not aligned to the device's %llu bytes for imported memory",
			bytes, base, (unsigned long long)a);
		return -EOPNOTSUPP;
	}
	r = find_region(e, NULL);
	if (!r) {
		eng_set_err(err, err_size, "two regions are imported already");
		return -ENOSPC;
	}
	r->base = base;
	r->bytes = bytes;
	int rc = import_buffer(e, r, err, err_size);
	if (rc < 0)
		region_free(e, r);
	return rc;
}

void eng_host_release(struct eng *e, void *base)
{
	struct host_region *r = base ? find_region(e, base) : NULL;

	if (!r)
		return;
	pthread_mutex_lock(&e->lock);
	bool writing = e->pending && e->has_target && e->target.base == base;
	pthread_mutex_unlock(&e->lock);
	/* Waiting beside the waiter thread is allowed; the fence stays
	 * signalled for it and for eng_complete. */
	if (writing)
		e->vk.vkWaitForFences(e->dev, 1, &e->fence, VK_TRUE, UINT64_MAX);
	/* A computation waiting for its pipelines writes the host copies
	 * instead: another region may come to the same address. */
	if (e->compiling && e->deferred.has_target && e->deferred.target.base == base)
		e->deferred.has_target = false;
	region_free(e, r);
}

int eng_host_fresh(const struct eng *e, uint32_t tables)
{
	for (int t = 0; t < STATE_N_TABLES; t++)
		if ((tables & STATE_BIT(t)) && !e->host_fresh[t])
			return 0;
	return 1;
}

void eng_host_free(struct eng *e)
{
	for (size_t i = 0; i < sizeof(e->regions) / sizeof(e->regions[0]); i++)
		region_free(e, &e->regions[i]);
}

/* The copies of the published parts of table t into the host copy: the
 * table, and after the aerial table the published panoramas. */
static uint32_t host_copies(const struct eng *e, int t, VkBufferCopy ret[2])
{
	VkDeviceSize published = aplan_published_bytes(&e->aplan);
	ret[0] = (VkBufferCopy){ e->published_offset[t], 0, e->table_bytes[t] };
	ret[1] = (VkBufferCopy){ e->panorama_offset, e->table_bytes[t], published };
	return t == STATE_AERIAL && published ? 2 : 1;
}

/* The copies of table t into target's memory: the table, or for aerial
 * perspective each published volume and panorama where target puts it. */
static uint32_t target_copies(const struct eng *e, int t, const struct eng_target *target,
			      VkBufferCopy ret[2 * ENG_MAX_VOLUMES])
{
	uint32_t n = 0;

	if (t != STATE_AERIAL) {
		ret[n++] = (VkBufferCopy){ e->published_offset[t], target->table_offset[t], e->table_bytes[t] };
		return n;
	}
	VkDeviceSize volume = e->table_bytes[t] / (e->aplan.n_volumes ? e->aplan.n_volumes : 1);
	VkDeviceSize panorama = aplan_panorama_texels(&e->aplan) * 16;
	uint32_t published = (uint32_t)(panorama ? aplan_published_bytes(&e->aplan) / panorama : 0);
	for (uint32_t v = 0; v < e->aplan.n_volumes && v < ENG_MAX_VOLUMES; v++) {
		uint64_t to = v == 0 ? target->table_offset[t] : target->volume_offset[v];
		if (to != ENG_NOWHERE)
			ret[n++] = (VkBufferCopy){ e->published_offset[t] + v * volume, to, volume };
	}
	for (uint32_t k = 0; k < published && k < ENG_MAX_VOLUMES; k++)
		if (target->panorama_offset[k] != ENG_NOWHERE)
			ret[n++] = (VkBufferCopy){ e->panorama_offset + k * panorama,
						   target->panorama_offset[k], panorama };
	return n;
}

void eng_record_publish(struct eng *e, const struct sky_state *s, const struct eng_target *target,
			uint32_t copy)
{
	const VkMemoryBarrier to_copy = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT, .dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT };
	struct host_region *region = target && target->base ? find_region(e, target->base) : NULL;
	uint32_t to_region = region ? target->tables : 0;
	/* The host copies: of the tables asked for without imported memory;
	 * with it, only where float16 storage is checked on the host
	 * (eng_f16_range). Where the host reads the device's memory there is
	 * nothing to copy. */
	uint32_t to_host = region ? (s->quality.storage == STATE_F16 ? copy : 0)
				  : copy | (target ? target->tables : 0);

	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
				   VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &to_copy, 0, NULL, 0, NULL);
	for (int t = 0; t < STATE_N_TABLES; t++) {
		VkBufferCopy c[2 * ENG_MAX_VOLUMES];
		if ((to_region & STATE_BIT(t)) && e->table_bytes[t])
			e->vk.vkCmdCopyBuffer(e->cmd, e->table[t].buf, region->buf,
					      target_copies(e, t, target, c), c);
		if ((to_host & STATE_BIT(t)) && !e->direct[t] && !(e->host_fresh[t] && !(copy & STATE_BIT(t))))
			e->vk.vkCmdCopyBuffer(e->cmd, e->table[t].buf, e->readback[t].buf, host_copies(e, t, c), c);
		if (e->direct[t] || (to_host & STATE_BIT(t)))
			e->host_fresh[t] = true;
		else if (copy & STATE_BIT(t))
			e->host_fresh[t] = false;
	}
	/* The host reads the copies, the pack pass's scales, and the tables
	 * the device wrote into imported memory. */
	VkMemoryBarrier to_host_barrier = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT,
		.dstAccessMask = VK_ACCESS_HOST_READ_BIT };
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
				   VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host_barrier, 0, NULL, 0, NULL);
}
