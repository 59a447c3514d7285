/* vkcheck.h - the engine's checked Vulkan: every call goes through VK_TRY,
 * which names the call, its result and the call site; and the memory type
 * a buffer gets. One header for every file of the engine (render/rvk.c
 * keeps its own copy: skyrender is the example a client copies, and links
 * libsky only). */
#ifndef SKYD_VKCHECK_H
#define SKYD_VKCHECK_H

#include <errno.h>
#include <stddef.h>
#include <stdint.h>

#include "vkfn.h"

/* "VK_ERROR_DEVICE_LOST" and the like; "VkResult" for one not listed. */
const char *vkcheck_result_name(VkResult r);

/* The index of a memory type of props that type_bits allows and that has
 * every flag of want, one with every flag of prefer too if there is one;
 * -1 when none has want. */
int vkcheck_find_memory(const VkPhysicalDeviceMemoryProperties *props, uint32_t type_bits,
			VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer);

/* Says in err which call failed with what, where. */
void vkcheck_describe(char *err, size_t err_size, const char *call, VkResult r, const char *file,
		      int line);

/* On failure writes "CALL failed: NAME (N) at FILE:LINE" to err (err,
 * err_size and an int rc in scope), sets rc to -ENOMEM or -EIO and jumps
 * to the function's one cleanup label, fail. */
#define VK_TRY(call)                                                                 \
	do {                                                                         \
		VkResult vk_r_ = (call);                                             \
		if (vk_r_ != VK_SUCCESS) {                                           \
			vkcheck_describe(err, err_size, #call, vk_r_, __FILE_NAME__, __LINE__); \
			rc = vk_r_ == VK_ERROR_OUT_OF_HOST_MEMORY ? -ENOMEM : -EIO;  \
			goto fail;                                                   \
		}                                                                    \
	} while (0)

#endif
