/* eng_cache.c - the compiled pipelines kept between runs: a VkPipelineCache
 * in a file of skyd's cache directory, named after the device, so that a
 * later skyd on the same device and driver skips the compilation that
 * makes its first computations slow (docs/performance.md, "The first
 * computation"). */
#include "eng_internal.h"

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* A cache file larger than this is not read: no driver's cache of a few
 * compute pipelines comes near it. */
#define CACHE_MAX_BYTES (64u << 20)

/* The file's contents (malloc'd) in ret and its size, or -errno. */
static int read_file(const char *path, void **ret, size_t *ret_bytes)
{
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	struct stat st;
	int rc = 0;

	if (fd < 0)
		return -errno;
	if (fstat(fd, &st) < 0 || st.st_size <= 0 || st.st_size > CACHE_MAX_BYTES) {
		close(fd);
		return -EINVAL;
	}
	uint8_t *p = malloc((size_t)st.st_size);
	size_t got = 0;
	while (p && got < (size_t)st.st_size) {
		ssize_t n = read(fd, p + got, (size_t)st.st_size - got);
		if (n <= 0) {
			rc = n < 0 ? -errno : -EIO;
			break;
		}
		got += (size_t)n;
	}
	close(fd);
	if (!p || rc < 0) {
		free(p);
		return p ? rc : -ENOMEM;
	}
	*ret = p;
	*ret_bytes = got;
	return 0;
}

/* Whether data is a cache of this device and driver. Vulkan drivers must
 * check the header themselves; checking it here too keeps a file written
 * by another driver, or damaged, away from one that trusts it. */
static bool cache_fits(const struct eng *e, const void *data, size_t bytes)
{
	VkPhysicalDeviceProperties props;
	VkPipelineCacheHeaderVersionOne h;

	if (bytes < sizeof(h))
		return false;
	memcpy(&h, data, sizeof(h));
	e->vk.vkGetPhysicalDeviceProperties(e->phys, &props);
	return h.headerSize >= sizeof(h) && h.headerSize <= bytes &&
	       h.headerVersion == VK_PIPELINE_CACHE_HEADER_VERSION_ONE && h.vendorID == props.vendorID &&
	       h.deviceID == props.deviceID && !memcmp(h.pipelineCacheUUID, props.pipelineCacheUUID, VK_UUID_SIZE);
}

int eng_use_cache_dir(struct eng *e, const char *dir, char *err, size_t err_size)
{
	void *data = NULL;
	size_t bytes = 0;
	char path[4096];
	int rc = 0;

	if (!dir || !*dir)
		return -EINVAL;
	if (snprintf(path, sizeof(path), "%s/pipelines-%04x-%04x.bin", dir, e->info.vendor_id,
		     e->info.device_id) >= (int)sizeof(path)) {
		eng_set_err(err, err_size, "cache directory '%s': path too long", dir);
		return -ENAMETOOLONG;
	}
	if (read_file(path, &data, &bytes) < 0 || !cache_fits(e, data, bytes)) {
		free(data);
		data = NULL;
		bytes = 0;
	}
	VkPipelineCacheCreateInfo ci = { .sType = VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO,
		.initialDataSize = bytes, .pInitialData = data };
	VkPipelineCache cache;
	VK_TRY(e->vk.vkCreatePipelineCache(e->dev, &ci, NULL, &cache));
	if (e->pipeline_cache)
		e->vk.vkDestroyPipelineCache(e->dev, e->pipeline_cache, NULL);
	e->pipeline_cache = cache;
	free(e->cache_path);
	e->cache_path = strdup(path);
	/* A cache read whole needs no rewrite until a pipeline is made. */
	e->pipelines_saved = data ? e->pipelines_created : 0;
	if (!e->cache_path)
		rc = -ENOMEM;
fail:
	free(data);
	return rc;
}

void eng_save_cache(struct eng *e)
{
	size_t bytes = 0;
	void *data = NULL;
	char tmp[4096 + 8];

	if (!e->pipeline_cache || !e->cache_path || e->pipelines_created <= e->pipelines_saved)
		return;
	if (e->vk.vkGetPipelineCacheData(e->dev, e->pipeline_cache, &bytes, NULL) != VK_SUCCESS ||
	    !bytes || bytes > CACHE_MAX_BYTES || !(data = malloc(bytes)) ||
	    e->vk.vkGetPipelineCacheData(e->dev, e->pipeline_cache, &bytes, data) != VK_SUCCESS) {
		free(data);
		return;
	}
	/* Written beside it and renamed over it: a reader never sees half a
	 * file, and a failure leaves the old one. */
	snprintf(tmp, sizeof(tmp), "%s.tmp", e->cache_path);
	int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
	bool ok = fd >= 0 && write(fd, data, bytes) == (ssize_t)bytes;
	if (fd >= 0 && close(fd) < 0)
		ok = false;
	if (ok && rename(tmp, e->cache_path) == 0)
		e->pipelines_saved = e->pipelines_created;
	else if (fd >= 0)
		unlink(tmp);
	free(data);
}
