/* test_glsl_vk.h - the little Vulkan the GLSL library's tests need: a device
 * (the first with a compute queue: lavapipe here), host-visible buffers,
 * sampled images uploaded from host memory, and one compute dispatch of a
 * SPIR-V module over a descriptor set of those. The loader is opened with
 * dlopen, so a machine without one gets -ENOENT (the test exits 77) rather
 * than a binary that does not start. Aborts the test (exit 1) on any other
 * Vulkan failure, naming the call: a test has no recovery to make. */
#ifndef SKYD_TEST_GLSL_VK_H
#define SKYD_TEST_GLSL_VK_H

#include <dlfcn.h>
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define VK_NO_PROTOTYPES
#include <vulkan/vulkan.h>

#define GVK_INSTANCE_FNS(X)                                          \
	X(vkDestroyInstance) X(vkEnumeratePhysicalDevices)           \
	X(vkGetPhysicalDeviceProperties)                             \
	X(vkGetPhysicalDeviceQueueFamilyProperties)                  \
	X(vkGetPhysicalDeviceMemoryProperties)                       \
	X(vkGetPhysicalDeviceFormatProperties) X(vkCreateDevice)     \
	X(vkGetDeviceProcAddr)
#define GVK_DEVICE_FNS(X)                                                           \
	X(vkDestroyDevice) X(vkGetDeviceQueue) X(vkCreateBuffer) X(vkDestroyBuffer)  \
	X(vkGetBufferMemoryRequirements) X(vkAllocateMemory) X(vkFreeMemory)        \
	X(vkBindBufferMemory) X(vkMapMemory) X(vkCreateImage) X(vkDestroyImage)     \
	X(vkGetImageMemoryRequirements) X(vkBindImageMemory) X(vkCreateImageView)   \
	X(vkDestroyImageView) X(vkCreateSampler) X(vkDestroySampler)                \
	X(vkCreateShaderModule) X(vkDestroyShaderModule)                            \
	X(vkCreateDescriptorSetLayout) X(vkDestroyDescriptorSetLayout)              \
	X(vkCreatePipelineLayout) X(vkDestroyPipelineLayout)                        \
	X(vkCreateComputePipelines) X(vkDestroyPipeline)                            \
	X(vkCreateDescriptorPool) X(vkDestroyDescriptorPool)                        \
	X(vkAllocateDescriptorSets) X(vkUpdateDescriptorSets)                       \
	X(vkCreateCommandPool) X(vkDestroyCommandPool)                              \
	X(vkAllocateCommandBuffers) X(vkBeginCommandBuffer) X(vkEndCommandBuffer)   \
	X(vkCmdPipelineBarrier) X(vkCmdCopyBufferToImage) X(vkCmdBindPipeline)      \
	X(vkCmdBindDescriptorSets) X(vkCmdDispatch) X(vkQueueSubmit)                \
	X(vkQueueWaitIdle) X(vkResetCommandPool)

#define GVK_DECLARE(name) PFN_##name name;

#define GVK_MAX_BUFFERS 16
#define GVK_MAX_IMAGES 8

struct gvk_buffer {
	VkBuffer buf;
	VkDeviceMemory mem;
	void *map;
	VkDeviceSize bytes;
};

struct gvk_image {
	VkImage image;
	VkDeviceMemory mem;
	VkImageView view;
	VkSampler sampler;
};

struct gvk {
	void *lib;
	PFN_vkGetInstanceProcAddr vkGetInstanceProcAddr;
	PFN_vkCreateInstance vkCreateInstance;
	GVK_INSTANCE_FNS(GVK_DECLARE)
	GVK_DEVICE_FNS(GVK_DECLARE)
	VkInstance inst;
	VkPhysicalDevice phys;
	VkDevice dev;
	VkQueue queue;
	uint32_t family;
	VkCommandPool pool;
	VkCommandBuffer cmd;
	VkPhysicalDeviceMemoryProperties memprops;
	char device_name[VK_MAX_PHYSICAL_DEVICE_NAME_SIZE];
	struct gvk_buffer buffers[GVK_MAX_BUFFERS];
	struct gvk_image images[GVK_MAX_IMAGES];
	int n_buffers, n_images;
};

#define GVK_TRY(call)                                                               \
	do {                                                                        \
		VkResult r_ = (call);                                               \
		if (r_ != VK_SUCCESS) {                                             \
			fprintf(stderr, "%s:%d: %s: VkResult %d\n", __FILE__, __LINE__, \
				#call, (int)r_);                                    \
			exit(1);                                                    \
		}                                                                   \
	} while (0)

/* Opens the loader and the first device with a compute queue. 0, or
 * -ENOENT / -ENODEV (no loader, no instance, no device: skip). */
static inline int gvk_open(struct gvk *g)
{
	memset(g, 0, sizeof(*g));
	g->lib = dlopen("libvulkan.so.1", RTLD_NOW | RTLD_LOCAL);
	if (!g->lib)
		return -ENOENT;
	g->vkGetInstanceProcAddr = (PFN_vkGetInstanceProcAddr)dlsym(g->lib, "vkGetInstanceProcAddr");
	if (!g->vkGetInstanceProcAddr)
		return -ENOENT;
	g->vkCreateInstance = (PFN_vkCreateInstance)g->vkGetInstanceProcAddr(NULL, "vkCreateInstance");
	VkApplicationInfo app = { .sType = VK_STRUCTURE_TYPE_APPLICATION_INFO,
				  .pApplicationName = "skyd-test-glsl", .apiVersion = VK_API_VERSION_1_1 };
	VkInstanceCreateInfo ici = { .sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO, .pApplicationInfo = &app };
	if (!g->vkCreateInstance || g->vkCreateInstance(&ici, NULL, &g->inst) != VK_SUCCESS)
		return -ENODEV;
#define GVK_LOAD_I(name) g->name = (PFN_##name)g->vkGetInstanceProcAddr(g->inst, #name);
	GVK_INSTANCE_FNS(GVK_LOAD_I)
	VkPhysicalDevice phys[8];
	uint32_t n = 8;
	if (g->vkEnumeratePhysicalDevices(g->inst, &n, phys) < 0 || n == 0)
		return -ENODEV;
	for (uint32_t i = 0; i < n && !g->phys; i++) {
		VkQueueFamilyProperties q[16];
		uint32_t nq = 16;
		g->vkGetPhysicalDeviceQueueFamilyProperties(phys[i], &nq, q);
		for (uint32_t f = 0; f < nq; f++)
			if (q[f].queueFlags & VK_QUEUE_COMPUTE_BIT) {
				g->phys = phys[i];
				g->family = f;
				break;
			}
	}
	if (!g->phys)
		return -ENODEV;
	VkPhysicalDeviceProperties props;
	g->vkGetPhysicalDeviceProperties(g->phys, &props);
	snprintf(g->device_name, sizeof(g->device_name), "%s", props.deviceName);
	g->vkGetPhysicalDeviceMemoryProperties(g->phys, &g->memprops);
	float prio = 1.0f;
	VkDeviceQueueCreateInfo qci = { .sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
					.queueFamilyIndex = g->family, .queueCount = 1,
					.pQueuePriorities = &prio };
	VkDeviceCreateInfo dci = { .sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
				   .queueCreateInfoCount = 1, .pQueueCreateInfos = &qci };
	GVK_TRY(g->vkCreateDevice(g->phys, &dci, NULL, &g->dev));
#define GVK_LOAD_D(name) g->name = (PFN_##name)g->vkGetDeviceProcAddr(g->dev, #name);
	GVK_DEVICE_FNS(GVK_LOAD_D)
	g->vkGetDeviceQueue(g->dev, g->family, 0, &g->queue);
	VkCommandPoolCreateInfo pci = { .sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
					.queueFamilyIndex = g->family };
	GVK_TRY(g->vkCreateCommandPool(g->dev, &pci, NULL, &g->pool));
	VkCommandBufferAllocateInfo cai = { .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
					    .commandPool = g->pool,
					    .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
					    .commandBufferCount = 1 };
	GVK_TRY(g->vkAllocateCommandBuffers(g->dev, &cai, &g->cmd));
	return 0;
}

/* True when the format can be sampled with linear filtering (optional for
 * R32G32B32A32_SFLOAT in Vulkan). */
static inline int gvk_linear_ok(struct gvk *g, VkFormat f)
{
	VkFormatProperties p;
	g->vkGetPhysicalDeviceFormatProperties(g->phys, f, &p);
	return (p.optimalTilingFeatures & VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT) != 0;
}

static inline uint32_t gvk_memory_type(struct gvk *g, uint32_t bits, VkMemoryPropertyFlags want)
{
	for (uint32_t i = 0; i < g->memprops.memoryTypeCount; i++)
		if ((bits & (1u << i)) && (g->memprops.memoryTypes[i].propertyFlags & want) == want)
			return i;
	fprintf(stderr, "no memory type with flags %#x\n", (unsigned)want);
	exit(1);
}

/* A host-visible, coherent buffer of bytes, mapped; owned by g. */
static inline struct gvk_buffer *gvk_buffer_new(struct gvk *g, VkDeviceSize bytes, VkBufferUsageFlags usage)
{
	if (g->n_buffers == GVK_MAX_BUFFERS)
		exit(1);
	struct gvk_buffer *b = &g->buffers[g->n_buffers++];
	VkBufferCreateInfo bci = { .sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO, .size = bytes,
				   .usage = usage, .sharingMode = VK_SHARING_MODE_EXCLUSIVE };
	GVK_TRY(g->vkCreateBuffer(g->dev, &bci, NULL, &b->buf));
	VkMemoryRequirements req;
	g->vkGetBufferMemoryRequirements(g->dev, b->buf, &req);
	VkMemoryAllocateInfo mai = { .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
				     .allocationSize = req.size,
				     .memoryTypeIndex = gvk_memory_type(g, req.memoryTypeBits,
									VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
									VK_MEMORY_PROPERTY_HOST_COHERENT_BIT) };
	GVK_TRY(g->vkAllocateMemory(g->dev, &mai, NULL, &b->mem));
	GVK_TRY(g->vkBindBufferMemory(g->dev, b->buf, b->mem, 0));
	GVK_TRY(g->vkMapMemory(g->dev, b->mem, 0, VK_WHOLE_SIZE, 0, &b->map));
	b->bytes = bytes;
	return b;
}

static inline void gvk_submit(struct gvk *g)
{
	GVK_TRY(g->vkEndCommandBuffer(g->cmd));
	VkSubmitInfo si = { .sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1,
			    .pCommandBuffers = &g->cmd };
	GVK_TRY(g->vkQueueSubmit(g->queue, 1, &si, VK_NULL_HANDLE));
	GVK_TRY(g->vkQueueWaitIdle(g->queue));
	GVK_TRY(g->vkResetCommandPool(g->dev, g->pool, 0));
}

static inline void gvk_begin(struct gvk *g)
{
	VkCommandBufferBeginInfo bi = { .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
					.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT };
	GVK_TRY(g->vkBeginCommandBuffer(g->cmd, &bi));
}

/* A sampled image (3-D when depth > 1) of format holding bytes of tightly
 * packed texels, row 0 first, as a client uploads a table; a linear sampler
 * clamping every axis but u when repeat_u. Owned by g. */
static inline struct gvk_image *gvk_image_new(struct gvk *g, VkFormat format, uint32_t w, uint32_t h,
					      uint32_t d, const void *texels, VkDeviceSize bytes,
					      int repeat_u, int three_d)
{
	if (g->n_images == GVK_MAX_IMAGES)
		exit(1);
	struct gvk_image *im = &g->images[g->n_images++];
	VkImageCreateInfo ici = { .sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
				  .imageType = three_d ? VK_IMAGE_TYPE_3D : VK_IMAGE_TYPE_2D,
				  .format = format, .extent = { w, h, d }, .mipLevels = 1,
				  .arrayLayers = 1, .samples = VK_SAMPLE_COUNT_1_BIT,
				  .tiling = VK_IMAGE_TILING_OPTIMAL,
				  .usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
				  .sharingMode = VK_SHARING_MODE_EXCLUSIVE,
				  .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED };
	GVK_TRY(g->vkCreateImage(g->dev, &ici, NULL, &im->image));
	VkMemoryRequirements req;
	g->vkGetImageMemoryRequirements(g->dev, im->image, &req);
	VkMemoryAllocateInfo mai = { .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
				     .allocationSize = req.size,
				     .memoryTypeIndex = gvk_memory_type(g, req.memoryTypeBits, 0) };
	GVK_TRY(g->vkAllocateMemory(g->dev, &mai, NULL, &im->mem));
	GVK_TRY(g->vkBindImageMemory(g->dev, im->image, im->mem, 0));

	struct gvk_buffer *staging = gvk_buffer_new(g, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
	memcpy(staging->map, texels, bytes);
	gvk_begin(g);
	VkImageSubresourceRange range = { VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1 };
	VkImageMemoryBarrier to_dst = { .sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER,
					.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
					.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED,
					.newLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
					.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
					.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
					.image = im->image, .subresourceRange = range };
	g->vkCmdPipelineBarrier(g->cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
				0, 0, NULL, 0, NULL, 1, &to_dst);
	VkBufferImageCopy copy = { .imageSubresource = { VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1 },
				   .imageExtent = { w, h, d } };
	g->vkCmdCopyBufferToImage(g->cmd, staging->buf, im->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
				  &copy);
	VkImageMemoryBarrier to_read = to_dst;
	to_read.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
	to_read.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
	to_read.oldLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
	to_read.newLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
	g->vkCmdPipelineBarrier(g->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
				VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0, NULL, 0, NULL, 1, &to_read);
	gvk_submit(g);

	VkImageViewCreateInfo vci = { .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
				      .image = im->image,
				      .viewType = three_d ? VK_IMAGE_VIEW_TYPE_3D : VK_IMAGE_VIEW_TYPE_2D,
				      .format = format, .subresourceRange = range };
	GVK_TRY(g->vkCreateImageView(g->dev, &vci, NULL, &im->view));
	VkSamplerCreateInfo sci = { .sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO,
				    .magFilter = VK_FILTER_LINEAR, .minFilter = VK_FILTER_LINEAR,
				    .mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST,
				    .addressModeU = repeat_u ? VK_SAMPLER_ADDRESS_MODE_REPEAT
							     : VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
				    .addressModeV = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
				    .addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
				    .maxLod = 0.0f };
	GVK_TRY(g->vkCreateSampler(g->dev, &sci, NULL, &im->sampler));
	return im;
}

/* One binding of gvk_dispatch: a buffer (uniform or storage) or an image. */
struct gvk_binding {
	VkDescriptorType type;
	struct gvk_buffer *buffer;
	struct gvk_image *image;
};

/* Runs spv (words bytes long) once over groups_x workgroups with bindings
 * 0 .. n - 1 in set 0, and waits for it. */
static inline void gvk_dispatch(struct gvk *g, const uint32_t *spv, size_t spv_bytes,
				const struct gvk_binding *b, uint32_t n, uint32_t groups_x)
{
	VkDescriptorSetLayoutBinding lb[16];
	VkDescriptorPoolSize sizes[16];
	VkWriteDescriptorSet writes[16];
	VkDescriptorBufferInfo bufs[16];
	VkDescriptorImageInfo imgs[16];
	for (uint32_t i = 0; i < n; i++) {
		lb[i] = (VkDescriptorSetLayoutBinding){ .binding = i, .descriptorType = b[i].type,
							.descriptorCount = 1,
							.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT };
		sizes[i] = (VkDescriptorPoolSize){ b[i].type, 1 };
	}
	VkDescriptorSetLayoutCreateInfo lci = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
						.bindingCount = n, .pBindings = lb };
	VkDescriptorSetLayout layout;
	GVK_TRY(g->vkCreateDescriptorSetLayout(g->dev, &lci, NULL, &layout));
	VkPipelineLayoutCreateInfo plci = { .sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
					    .setLayoutCount = 1, .pSetLayouts = &layout };
	VkPipelineLayout pl;
	GVK_TRY(g->vkCreatePipelineLayout(g->dev, &plci, NULL, &pl));
	VkShaderModuleCreateInfo smci = { .sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO,
					  .codeSize = spv_bytes, .pCode = spv };
	VkShaderModule mod;
	GVK_TRY(g->vkCreateShaderModule(g->dev, &smci, NULL, &mod));
	VkComputePipelineCreateInfo cpci = { .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
					     .stage = { .sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
							.stage = VK_SHADER_STAGE_COMPUTE_BIT,
							.module = mod, .pName = "main" },
					     .layout = pl };
	VkPipeline pipe;
	GVK_TRY(g->vkCreateComputePipelines(g->dev, VK_NULL_HANDLE, 1, &cpci, NULL, &pipe));
	VkDescriptorPoolCreateInfo dpci = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
					    .maxSets = 1, .poolSizeCount = n, .pPoolSizes = sizes };
	VkDescriptorPool dpool;
	GVK_TRY(g->vkCreateDescriptorPool(g->dev, &dpci, NULL, &dpool));
	VkDescriptorSetAllocateInfo dsai = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
					     .descriptorPool = dpool, .descriptorSetCount = 1,
					     .pSetLayouts = &layout };
	VkDescriptorSet set;
	GVK_TRY(g->vkAllocateDescriptorSets(g->dev, &dsai, &set));
	for (uint32_t i = 0; i < n; i++) {
		writes[i] = (VkWriteDescriptorSet){ .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
						    .dstSet = set, .dstBinding = i, .descriptorCount = 1,
						    .descriptorType = b[i].type };
		if (b[i].image) {
			imgs[i] = (VkDescriptorImageInfo){ b[i].image->sampler, b[i].image->view,
							   VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL };
			writes[i].pImageInfo = &imgs[i];
		} else {
			bufs[i] = (VkDescriptorBufferInfo){ b[i].buffer->buf, 0, VK_WHOLE_SIZE };
			writes[i].pBufferInfo = &bufs[i];
		}
	}
	g->vkUpdateDescriptorSets(g->dev, n, writes, 0, NULL);
	gvk_begin(g);
	g->vkCmdBindPipeline(g->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipe);
	g->vkCmdBindDescriptorSets(g->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pl, 0, 1, &set, 0, NULL);
	g->vkCmdDispatch(g->cmd, groups_x, 1, 1);
	VkMemoryBarrier mb = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
			       .srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT,
			       .dstAccessMask = VK_ACCESS_HOST_READ_BIT };
	g->vkCmdPipelineBarrier(g->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0,
				1, &mb, 0, NULL, 0, NULL);
	gvk_submit(g);
	g->vkDestroyDescriptorPool(g->dev, dpool, NULL);
	g->vkDestroyPipeline(g->dev, pipe, NULL);
	g->vkDestroyShaderModule(g->dev, mod, NULL);
	g->vkDestroyPipelineLayout(g->dev, pl, NULL);
	g->vkDestroyDescriptorSetLayout(g->dev, layout, NULL);
}

/* Releases the images and buffers beyond the first mark_buffers and
 * mark_images (counts taken earlier), keeping the device: a test that
 * uploads several generations in turn. */
static inline void gvk_release_to(struct gvk *g, int mark_buffers, int mark_images)
{
	for (int i = mark_images; i < g->n_images; i++) {
		g->vkDestroySampler(g->dev, g->images[i].sampler, NULL);
		g->vkDestroyImageView(g->dev, g->images[i].view, NULL);
		g->vkDestroyImage(g->dev, g->images[i].image, NULL);
		g->vkFreeMemory(g->dev, g->images[i].mem, NULL);
	}
	for (int i = mark_buffers; i < g->n_buffers; i++) {
		g->vkDestroyBuffer(g->dev, g->buffers[i].buf, NULL);
		g->vkFreeMemory(g->dev, g->buffers[i].mem, NULL);
	}
	g->n_images = mark_images;
	g->n_buffers = mark_buffers;
}

/* Frees the images and buffers (after the queue is idle), then the device. */
static inline void gvk_close(struct gvk *g)
{
	if (g->dev) {
		gvk_release_to(g, 0, 0);
		g->vkDestroyCommandPool(g->dev, g->pool, NULL);
		g->vkDestroyDevice(g->dev, NULL);
	}
	if (g->inst)
		g->vkDestroyInstance(g->inst, NULL);
	if (g->lib)
		dlclose(g->lib);
	memset(g, 0, sizeof(*g));
}

#endif
