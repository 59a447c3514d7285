/* vkcheck.c - the names of Vulkan results and the choice of a memory type. */
#include "vkcheck.h"

#include <stdio.h>

const char *vkcheck_result_name(VkResult r)
{
	switch (r) {
	case VK_SUCCESS: return "VK_SUCCESS";
	case VK_NOT_READY: return "VK_NOT_READY";
	case VK_TIMEOUT: return "VK_TIMEOUT";
	case VK_INCOMPLETE: return "VK_INCOMPLETE";
	case VK_ERROR_OUT_OF_HOST_MEMORY: return "VK_ERROR_OUT_OF_HOST_MEMORY";
	case VK_ERROR_OUT_OF_DEVICE_MEMORY: return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
	case VK_ERROR_INITIALIZATION_FAILED: return "VK_ERROR_INITIALIZATION_FAILED";
	case VK_ERROR_DEVICE_LOST: return "VK_ERROR_DEVICE_LOST";
	case VK_ERROR_MEMORY_MAP_FAILED: return "VK_ERROR_MEMORY_MAP_FAILED";
	case VK_ERROR_EXTENSION_NOT_PRESENT: return "VK_ERROR_EXTENSION_NOT_PRESENT";
	case VK_ERROR_FEATURE_NOT_PRESENT: return "VK_ERROR_FEATURE_NOT_PRESENT";
	case VK_ERROR_INCOMPATIBLE_DRIVER: return "VK_ERROR_INCOMPATIBLE_DRIVER";
	case VK_ERROR_TOO_MANY_OBJECTS: return "VK_ERROR_TOO_MANY_OBJECTS";
	default: return "VkResult";
	}
}

int vkcheck_find_memory(const VkPhysicalDeviceMemoryProperties *props, uint32_t type_bits,
			VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer)
{
	int fallback = -1;
	for (uint32_t i = 0; i < props->memoryTypeCount; i++) {
		VkMemoryPropertyFlags f = props->memoryTypes[i].propertyFlags;
		if (!(type_bits & (1u << i)) || (f & want) != want)
			continue;
		if ((f & prefer) == prefer)
			return (int)i;
		if (fallback < 0)
			fallback = (int)i;
	}
	return fallback;
}

void vkcheck_describe(char *err, size_t err_size, const char *call, VkResult r, const char *file,
		      int line)
{
	if (err && err_size)
		snprintf(err, err_size, "%s failed: %s (%d) at %s:%d", call, vkcheck_result_name(r),
			 (int)r, file, line);
}
