/* rvk_internal.h - what the two files of skyrender's Vulkan module (rvk.c:
 * instance, device, images, upload, read-back; frame.c: pipelines and the
 * draw) share. Nothing outside render/ includes it. */
#ifndef SKYRENDER_RVK_INTERNAL_H
#define SKYRENDER_RVK_INTERNAL_H

#include <stdbool.h>
#include <stdint.h>
#include <vulkan/vulkan.h>

#include "rvk.h"
#include "skycloudmarch.h"

void rvk_set_err(char *err, size_t n, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
const char *rvk_result_name(VkResult r);

/* Every Vulkan call goes through VK_TRY: on failure it names the call and
 * the result in err and jumps to the function's one cleanup label, with rc
 * set to -ENOMEM or -EIO. VK_TRY, rvk_result_name and rvk.c's find_memory
 * are a copy of the engine's (daemon/engine/vkcheck.h), kept on purpose:
 * skyrender is the example a client copies, and it links libsky only. */
#define VK_TRY(call)                                                                     \
	do {                                                                             \
		VkResult vk_r_ = (call);                                                 \
		if (vk_r_ != VK_SUCCESS) {                                               \
			rvk_set_err(err, err_size, "%s failed: %s (%d) at %s:%d", #call, \
				    rvk_result_name(vk_r_), (int)vk_r_, __FILE_NAME__,   \
				    __LINE__);                                           \
			rc = vk_r_ == VK_ERROR_OUT_OF_HOST_MEMORY ? -ENOMEM : -EIO;      \
			goto fail;                                                       \
		}                                                                        \
	} while (0)

struct rvk_buffer {
	VkBuffer buf;
	VkDeviceMemory mem;
	VkDeviceSize bytes;
	void *map;			/* host-visible buffers only */
};

struct rvk_image {
	VkImage image;
	VkDeviceMemory mem;
	VkImageView view;
	VkFormat format;
	uint32_t width, height, depth;
};

/* The frame's uniform block (std140, every member a vec4 so that C and GLSL
 * agree without padding rules): the GLSL library's SkyState, then the
 * camera; render/shaders/frame.glsl declares it. */
struct rvk_frame_ubo {
	struct sky_gpu_state sky[RVK_MAX_AERIAL];	/* the same but for each volume's camera */
	float wall[4];			/* wall width, height (px); tile origin x, y (px) */
	float tile[4];			/* tile width, height (px); projection; tan(vfov / 2) */
	float cam_f[4];			/* wall camera forward (ENU); w: yaw (rad) */
	float cam_r[4];			/* right; w: aspect of the wall */
	float cam_u[4];			/* up; w: near plane (km) */
	float ambient_lx[4];		/* horizontal sky irradiance (rgb); w: disk flags */
	float terrain[4];		/* albedo (rgb); w: number of aerial textures */
	/* The clouds (skycloud_march.glsl's blocks; std140 rounds a layer up
	 * to 80 bytes): the slot's layers, their scene, the sun and its
	 * shadow map's frame, and x: the march's steps (0: no clouds), y:
	 * light steps (0: the shadow map). */
	struct { struct skycloud_layer l; float pad[2]; } layers[SKYCLOUD_MAX_LAYERS];
	float scene[6][4];
	float sun[6][4];
	float clouds[4];
};

/* The tables a frame samples, in binding order after the uniform block;
 * the aerial textures (one binding, an array) are the client's views'
 * volumes or panorama when it has them. */
enum rvk_table { RVK_TRANSMITTANCE, RVK_SKYVIEW, RVK_MULTISCATTER, RVK_CLOUD, RVK_SHADOW, RVK_AERIAL,
		 RVK_TABLES = RVK_AERIAL + RVK_MAX_AERIAL };

/* Where one table's texels come from in a slot and how they are stored. */
struct rvk_table_layout {
	uint32_t format;		/* enum sky_shm_format; 0: absent (a 1-texel stand-in) */
	uint32_t width, height, depth;
	uint64_t bytes;
	uint64_t staging_offset;
	uint32_t uploaded_generation;	/* sky_gpu_table.changed_generation the image holds; 0: none */
	bool from_view;			/* the aerial image holds a view's volume or
					 * panorama (whose generations count apart
					 * from the table's) */
	bool copy;			/* upload this table in the running upload */
};

struct rvk_set {
	struct rvk_image tables[RVK_TABLES];
	struct rvk_buffer staging;	/* the slot's texels as uploaded */
	struct rvk_buffer ubo;		/* struct rvk_frame_ubo */
	VkDescriptorSet desc;
	VkFence upload_fence;
	VkCommandBuffer upload_cmd;
	bool uploading;			/* a copy into the set is in flight */
	uint64_t generation;
	struct rvk_table_layout layout[RVK_TABLES];
};

struct rvk {
	struct rvk_options opt;
	VkInstance instance;
	VkPhysicalDevice phys;
	VkPhysicalDeviceMemoryProperties mem_props;
	char device_name[256];
	VkDevice dev;
	VkQueue queue;
	uint32_t queue_family;
	VkCommandPool pool;
	VkSampler sampler_clamp, sampler_wrap_u;

	/* The offscreen target and its read-back. */
	struct rvk_image colour, depth;
	struct rvk_buffer readback;
	VkCommandBuffer draw_cmd;
	VkFence draw_fence;

	/* frame.c */
	VkRenderPass pass;
	VkFramebuffer fb;
	VkDescriptorSetLayout set_layout;
	VkDescriptorPool desc_pool;
	VkPipelineLayout pipe_layout;
	VkPipeline sky_pipe, terrain_pipe;
	struct rvk_buffer terrain_vertices, terrain_indices;
	uint32_t terrain_index_count;

	struct rvk_set sets[2];
	int active;			/* index of the set frames draw from, -1 before the first */
};

/* rvk.c */
int rvk_buffer_new(struct rvk *r, VkDeviceSize bytes, VkBufferUsageFlags usage, bool host,
		   struct rvk_buffer *ret, char *err, size_t err_size);
void rvk_buffer_free(struct rvk *r, struct rvk_buffer *b);
int rvk_image_new(struct rvk *r, VkImageType type, VkFormat format, uint32_t w, uint32_t h,
		  uint32_t d, VkImageUsageFlags usage, VkImageAspectFlags aspect,
		  struct rvk_image *ret, char *err, size_t err_size);
void rvk_image_free(struct rvk *r, struct rvk_image *im);

/* frame.c: the render pass, pipelines and descriptor layout (after the
 * device and the target exist), their teardown, pointing a set's descriptor
 * at its images, and recording one frame into r->draw_cmd from set s. */
int rvk_frame_init(struct rvk *r, char *err, size_t err_size);
void rvk_frame_finish(struct rvk *r);
int rvk_frame_bind_set(struct rvk *r, struct rvk_set *s, char *err, size_t err_size);
int rvk_frame_record(struct rvk *r, const struct rvk_set *s, char *err, size_t err_size);

#endif
