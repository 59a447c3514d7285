/* vkfn.h - the Vulkan entry points the engine uses, loaded at run time.
 *
 * The loader is opened with dlopen so that a machine without it gets one
 * clear line naming the package instead of a dynamic-linker failure.
 * X(name) lists are expanded into a table of function pointers.
 */
#ifndef SKYD_VKFN_H
#define SKYD_VKFN_H

#define VK_NO_PROTOTYPES
#include <vulkan/vulkan.h>

#define VKFN_GLOBAL(X)                          \
	X(vkCreateInstance)                     \
	X(vkEnumerateInstanceExtensionProperties)

#define VKFN_INSTANCE(X)                             \
	X(vkDestroyInstance)                         \
	X(vkEnumeratePhysicalDevices)                \
	X(vkGetPhysicalDeviceProperties)             \
	X(vkGetPhysicalDeviceProperties2)            \
	X(vkGetPhysicalDeviceQueueFamilyProperties)  \
	X(vkGetPhysicalDeviceMemoryProperties)       \
	X(vkEnumerateDeviceExtensionProperties)      \
	X(vkCreateDevice)                            \
	X(vkGetDeviceProcAddr)

#define VKFN_DEVICE(X)                       \
	X(vkDestroyDevice)                   \
	X(vkGetDeviceQueue)                  \
	X(vkCreateBuffer)                    \
	X(vkDestroyBuffer)                   \
	X(vkCreateBufferView)                \
	X(vkDestroyBufferView)               \
	X(vkGetBufferMemoryRequirements)     \
	X(vkAllocateMemory)                  \
	X(vkFreeMemory)                      \
	X(vkBindBufferMemory)                \
	X(vkMapMemory)                       \
	X(vkInvalidateMappedMemoryRanges)    \
	X(vkFlushMappedMemoryRanges)         \
	X(vkCreateShaderModule)              \
	X(vkDestroyShaderModule)             \
	X(vkCreateDescriptorSetLayout)       \
	X(vkDestroyDescriptorSetLayout)      \
	X(vkCreatePipelineLayout)            \
	X(vkDestroyPipelineLayout)           \
	X(vkCreateComputePipelines)          \
	X(vkDestroyPipeline)                 \
	X(vkCreatePipelineCache)             \
	X(vkDestroyPipelineCache)            \
	X(vkGetPipelineCacheData)            \
	X(vkCreateDescriptorPool)            \
	X(vkDestroyDescriptorPool)           \
	X(vkAllocateDescriptorSets)          \
	X(vkUpdateDescriptorSets)            \
	X(vkCreateCommandPool)               \
	X(vkDestroyCommandPool)              \
	X(vkAllocateCommandBuffers)          \
	X(vkBeginCommandBuffer)              \
	X(vkEndCommandBuffer)                \
	X(vkCmdBindPipeline)                 \
	X(vkCmdBindDescriptorSets)           \
	X(vkCmdDispatch)                     \
	X(vkCmdPipelineBarrier)              \
	X(vkCmdCopyBuffer)                   \
	X(vkCmdCopyBufferToImage)            \
	X(vkCreateImage)                     \
	X(vkDestroyImage)                    \
	X(vkGetImageMemoryRequirements)      \
	X(vkBindImageMemory)                 \
	X(vkCreateImageView)                 \
	X(vkDestroyImageView)                \
	X(vkCreateSampler)                   \
	X(vkDestroySampler)                  \
	X(vkCmdFillBuffer)                   \
	X(vkCmdWriteTimestamp)               \
	X(vkCmdResetQueryPool)               \
	X(vkCreateQueryPool)                 \
	X(vkDestroyQueryPool)                \
	X(vkGetQueryPoolResults)             \
	X(vkCreateFence)                     \
	X(vkDestroyFence)                    \
	X(vkResetFences)                     \
	X(vkWaitForFences)                   \
	X(vkQueueSubmit)                     \
	X(vkDeviceWaitIdle)

struct vkfn {
#define VKFN_MEMBER(name) PFN_##name name;
	PFN_vkGetInstanceProcAddr vkGetInstanceProcAddr;
	VKFN_GLOBAL(VKFN_MEMBER)
	VKFN_INSTANCE(VKFN_MEMBER)
	VKFN_DEVICE(VKFN_MEMBER)
#undef VKFN_MEMBER
};

#endif
