/* rvk.c - skyrender's Vulkan device, offscreen target, table images and
 * their upload, and the read-back of a frame. The pipelines and the draw
 * are in frame.c. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "rvk_internal.h"
#include "skysample.h"

#define DEG (SKYMAP_PI / 180.0)

void rvk_set_err(char *err, size_t n, const char *fmt, ...)
{
	if (!err || !n)
		return;
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(err, n, fmt, ap);
	va_end(ap);
}

const char *rvk_result_name(VkResult r)
{
	switch (r) {
	case VK_NOT_READY: return "VK_NOT_READY";
	case VK_TIMEOUT: return "VK_TIMEOUT";
	case VK_ERROR_OUT_OF_HOST_MEMORY: return "VK_ERROR_OUT_OF_HOST_MEMORY";
	case VK_ERROR_OUT_OF_DEVICE_MEMORY: return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
	case VK_ERROR_INITIALIZATION_FAILED: return "VK_ERROR_INITIALIZATION_FAILED";
	case VK_ERROR_DEVICE_LOST: return "VK_ERROR_DEVICE_LOST";
	case VK_ERROR_EXTENSION_NOT_PRESENT: return "VK_ERROR_EXTENSION_NOT_PRESENT";
	case VK_ERROR_FEATURE_NOT_PRESENT: return "VK_ERROR_FEATURE_NOT_PRESENT";
	case VK_ERROR_INCOMPATIBLE_DRIVER: return "VK_ERROR_INCOMPATIBLE_DRIVER";
	case VK_ERROR_FORMAT_NOT_SUPPORTED: return "VK_ERROR_FORMAT_NOT_SUPPORTED";
	default: return "VkResult";
	}
}

/* Memory and objects ---------------------------------------------------------- */

static int find_memory(const struct rvk *r, uint32_t bits, VkMemoryPropertyFlags want,
		       VkMemoryPropertyFlags prefer)
{
	int fallback = -1;
	for (uint32_t i = 0; i < r->mem_props.memoryTypeCount; i++) {
		VkMemoryPropertyFlags f = r->mem_props.memoryTypes[i].propertyFlags;
		if (!(bits & (1u << i)) || (f & want) != want)
			continue;
		if ((f & prefer) == prefer)
			return (int)i;
		if (fallback < 0)
			fallback = (int)i;
	}
	return fallback;
}

static int bind_memory(struct rvk *r, const VkMemoryRequirements *req, bool host,
		       VkDeviceMemory *ret_mem, char *err, size_t err_size)
{
	VkMemoryPropertyFlags want = host ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
					    VK_MEMORY_PROPERTY_HOST_COHERENT_BIT : 0;
	int type = find_memory(r, req->memoryTypeBits, want,
			       host ? want : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
	int rc = 0;
	if (type < 0) {
		rvk_set_err(err, err_size, "no Vulkan memory type with flags 0x%x", want);
		return -ENOMEM;
	}
	VkMemoryAllocateInfo ai = { .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
		.allocationSize = req->size, .memoryTypeIndex = (uint32_t)type };
	VK_TRY(vkAllocateMemory(r->dev, &ai, NULL, ret_mem));
	return 0;
fail:
	return rc;
}

void rvk_buffer_free(struct rvk *r, struct rvk_buffer *b)
{
	if (b->buf)
		vkDestroyBuffer(r->dev, b->buf, NULL);
	if (b->mem)
		vkFreeMemory(r->dev, b->mem, NULL);
	memset(b, 0, sizeof(*b));
}

int rvk_buffer_new(struct rvk *r, VkDeviceSize bytes, VkBufferUsageFlags usage, bool host,
		   struct rvk_buffer *ret, char *err, size_t err_size)
{
	struct rvk_buffer b = { .bytes = bytes };
	VkBufferCreateInfo bi = { .sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO, .size = bytes,
		.usage = usage, .sharingMode = VK_SHARING_MODE_EXCLUSIVE };
	VkMemoryRequirements req;
	int rc = 0;

	VK_TRY(vkCreateBuffer(r->dev, &bi, NULL, &b.buf));
	vkGetBufferMemoryRequirements(r->dev, b.buf, &req);
	if ((rc = bind_memory(r, &req, host, &b.mem, err, err_size)) < 0)
		goto fail;
	VK_TRY(vkBindBufferMemory(r->dev, b.buf, b.mem, 0));
	if (host)
		VK_TRY(vkMapMemory(r->dev, b.mem, 0, VK_WHOLE_SIZE, 0, &b.map));
	*ret = b;
	return 0;
fail:
	rvk_buffer_free(r, &b);
	return rc;
}

void rvk_image_free(struct rvk *r, struct rvk_image *im)
{
	if (im->view)
		vkDestroyImageView(r->dev, im->view, NULL);
	if (im->image)
		vkDestroyImage(r->dev, im->image, NULL);
	if (im->mem)
		vkFreeMemory(r->dev, im->mem, NULL);
	memset(im, 0, sizeof(*im));
}

int rvk_image_new(struct rvk *r, VkImageType type, VkFormat format, uint32_t w, uint32_t h,
		  uint32_t d, VkImageUsageFlags usage, VkImageAspectFlags aspect,
		  struct rvk_image *ret, char *err, size_t err_size)
{
	struct rvk_image im = { .format = format, .width = w, .height = h, .depth = d };
	VkImageCreateInfo ii = { .sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO, .imageType = type,
		.format = format, .extent = { w, h, d }, .mipLevels = 1, .arrayLayers = 1,
		.samples = VK_SAMPLE_COUNT_1_BIT, .tiling = VK_IMAGE_TILING_OPTIMAL,
		.usage = usage, .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED };
	VkMemoryRequirements req;
	int rc = 0;

	VK_TRY(vkCreateImage(r->dev, &ii, NULL, &im.image));
	vkGetImageMemoryRequirements(r->dev, im.image, &req);
	if ((rc = bind_memory(r, &req, false, &im.mem, err, err_size)) < 0)
		goto fail;
	VK_TRY(vkBindImageMemory(r->dev, im.image, im.mem, 0));
	VkImageViewCreateInfo vi = { .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
		.image = im.image,
		.viewType = type == VK_IMAGE_TYPE_3D ? VK_IMAGE_VIEW_TYPE_3D : VK_IMAGE_VIEW_TYPE_2D,
		.format = format, .subresourceRange = { aspect, 0, 1, 0, 1 } };
	VK_TRY(vkCreateImageView(r->dev, &vi, NULL, &im.view));
	*ret = im;
	return 0;
fail:
	rvk_image_free(r, &im);
	return rc;
}

/* Device ------------------------------------------------------------------------ */

static int type_rank(VkPhysicalDeviceType t)
{
	switch (t) {
	case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 4;
	case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 3;
	case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
	case VK_PHYSICAL_DEVICE_TYPE_CPU: return 1;
	default: return 0;
	}
}

/* The graphics queue family of pd, or -1. */
static int graphics_family(VkPhysicalDevice pd)
{
	VkQueueFamilyProperties qf[16];
	uint32_t n = 16;
	vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, qf);
	for (uint32_t i = 0; i < n; i++)
		if (qf[i].queueFlags & VK_QUEUE_GRAPHICS_BIT)
			return (int)i;
	return -1;
}

/* Picks a device as skyd does: selector (or $SKYD_DEVICE) as an index or a
 * name substring, else the best type; only devices with a graphics queue. */
static int pick_device(struct rvk *r, const char *selector, char *err, size_t err_size)
{
	VkPhysicalDevice pds[16];
	uint32_t n = 16;
	int rc = 0, best = -1, best_rank = -1;

	VkResult vr = vkEnumeratePhysicalDevices(r->instance, &n, pds);
	if (vr != VK_INCOMPLETE)	/* more than 16: the first 16 will do */
		VK_TRY(vr);
	if (!selector || !*selector)
		selector = getenv("SKYD_DEVICE");
	for (uint32_t i = 0; i < n; i++) {
		VkPhysicalDeviceProperties p;
		vkGetPhysicalDeviceProperties(pds[i], &p);
		if (graphics_family(pds[i]) < 0)
			continue;
		if (selector && *selector) {
			char *end;
			unsigned long idx = strtoul(selector, &end, 10);
			if ((!*end && idx == i) || strcasestr(p.deviceName, selector)) {
				best = (int)i;
				break;
			}
		} else if (type_rank(p.deviceType) > best_rank) {
			best_rank = type_rank(p.deviceType);
			best = (int)i;
		}
	}
	if (best < 0) {
		rvk_set_err(err, err_size, selector && *selector ?
			    "device '%s': no such Vulkan device with graphics" :
			    "no Vulkan device with graphics%s: install mesa-vulkan-drivers (lavapipe) or a GPU driver",
			    selector ? selector : "");
		return -ENODEV;
	}
	r->phys = pds[best];
	VkPhysicalDeviceProperties p;
	vkGetPhysicalDeviceProperties(r->phys, &p);
	snprintf(r->device_name, sizeof(r->device_name), "%s", p.deviceName);
	vkGetPhysicalDeviceMemoryProperties(r->phys, &r->mem_props);
	r->queue_family = (uint32_t)graphics_family(r->phys);
	return 0;
fail:
	return rc;
}

static int device_init(struct rvk *r, char *err, size_t err_size)
{
	VkApplicationInfo app = { .sType = VK_STRUCTURE_TYPE_APPLICATION_INFO,
		.pApplicationName = "skyrender", .apiVersion = VK_API_VERSION_1_1 };
	VkInstanceCreateInfo ici = { .sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
		.pApplicationInfo = &app };
	int rc = 0;
	VkResult vr = vkCreateInstance(&ici, NULL, &r->instance);
	if (vr == VK_ERROR_INCOMPATIBLE_DRIVER || vr == VK_ERROR_INITIALIZATION_FAILED) {
		rvk_set_err(err, err_size, "no Vulkan driver: install mesa-vulkan-drivers (lavapipe) or a GPU driver");
		return -ENODEV;
	}
	VK_TRY(vr);
	if ((rc = pick_device(r, r->opt.device, err, err_size)) < 0)
		return rc;
	VkPhysicalDeviceFeatures have, want = { 0 };
	vkGetPhysicalDeviceFeatures(r->phys, &have);
	want.shaderClipDistance = have.shaderClipDistance;
	float prio = 1.0f;
	VkDeviceQueueCreateInfo qi = { .sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
		.queueFamilyIndex = r->queue_family, .queueCount = 1, .pQueuePriorities = &prio };
	VkDeviceCreateInfo di = { .sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
		.queueCreateInfoCount = 1, .pQueueCreateInfos = &qi, .pEnabledFeatures = &want };
	VK_TRY(vkCreateDevice(r->phys, &di, NULL, &r->dev));
	vkGetDeviceQueue(r->dev, r->queue_family, 0, &r->queue);
	VkCommandPoolCreateInfo pi = { .sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
		.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
		.queueFamilyIndex = r->queue_family };
	VK_TRY(vkCreateCommandPool(r->dev, &pi, NULL, &r->pool));
	VkCommandBuffer cmds[3];
	VkCommandBufferAllocateInfo ai = { .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
		.commandPool = r->pool, .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY, .commandBufferCount = 3 };
	VK_TRY(vkAllocateCommandBuffers(r->dev, &ai, cmds));
	r->draw_cmd = cmds[0];
	r->sets[0].upload_cmd = cmds[1];
	r->sets[1].upload_cmd = cmds[2];
	VkFenceCreateInfo fi = { .sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO };
	VK_TRY(vkCreateFence(r->dev, &fi, NULL, &r->draw_fence));
	VK_TRY(vkCreateFence(r->dev, &fi, NULL, &r->sets[0].upload_fence));
	VK_TRY(vkCreateFence(r->dev, &fi, NULL, &r->sets[1].upload_fence));
	/* Texel centres at (i + 0.5) / n with clamping to the edge texel, as
	 * proto/skysample.h reads the tables; the sky-view longitude wraps. */
	VkSamplerCreateInfo si = { .sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO,
		.magFilter = VK_FILTER_LINEAR, .minFilter = VK_FILTER_LINEAR,
		.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST,
		.addressModeU = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
		.addressModeV = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
		.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE };
	VK_TRY(vkCreateSampler(r->dev, &si, NULL, &r->sampler_clamp));
	si.addressModeU = VK_SAMPLER_ADDRESS_MODE_REPEAT;
	VK_TRY(vkCreateSampler(r->dev, &si, NULL, &r->sampler_wrap_u));
	return 0;
fail:
	return rc;
}

static int target_init(struct rvk *r, char *err, size_t err_size)
{
	uint32_t w = r->opt.camera.width, h = r->opt.camera.height;
	int rc = rvk_image_new(r, VK_IMAGE_TYPE_2D, VK_FORMAT_R32G32B32A32_SFLOAT, w, h, 1,
			       VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
			       VK_IMAGE_ASPECT_COLOR_BIT, &r->colour, err, err_size);
	if (rc == 0)
		rc = rvk_image_new(r, VK_IMAGE_TYPE_2D, VK_FORMAT_D32_SFLOAT, w, h, 1,
				   VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
				   VK_IMAGE_ASPECT_DEPTH_BIT, &r->depth, err, err_size);
	if (rc == 0)
		rc = rvk_buffer_new(r, (VkDeviceSize)w * h * 16, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
				    true, &r->readback, err, err_size);
	return rc;
}

static int check_options(const struct rvk_options *o, char *err, size_t err_size)
{
	const struct rvk_camera *c = &o->camera;
	if (!c->width || !c->height || c->width > 16384 || c->height > 16384 || !c->cols ||
	    !c->rows || c->col >= c->cols || c->row >= c->rows || !isfinite(c->yaw_deg) ||
	    !(fabs(c->pitch_deg) <= 90.0) || (c->projection == RVK_PERSPECTIVE &&
	    !(c->vfov_deg > 0.0 && c->vfov_deg < 180.0))) {
		rvk_set_err(err, err_size, "bad camera");
		return -EINVAL;
	}
	return 0;
}

int rvk_new(const struct rvk_options *o, char *err, size_t err_size, struct rvk **ret)
{
	if (!o || !ret)
		return -EINVAL;
	int rc = check_options(o, err, err_size);
	if (rc < 0)
		return rc;
	struct rvk *r = calloc(1, sizeof(*r));
	if (!r)
		return -ENOMEM;
	r->opt = *o;
	r->active = -1;
	if ((rc = device_init(r, err, err_size)) < 0 || (rc = target_init(r, err, err_size)) < 0 ||
	    (rc = rvk_frame_init(r, err, err_size)) < 0) {
		rvk_free(r);
		return rc;
	}
	*ret = r;
	return 0;
}

static void set_free(struct rvk *r, struct rvk_set *s)
{
	for (int t = 0; t < RVK_TABLES; t++)
		rvk_image_free(r, &s->tables[t]);
	rvk_buffer_free(r, &s->staging);
	rvk_buffer_free(r, &s->ubo);
	if (s->upload_fence)
		vkDestroyFence(r->dev, s->upload_fence, NULL);
}

void rvk_free(struct rvk *r)
{
	if (!r)
		return;
	if (r->dev) {
		vkDeviceWaitIdle(r->dev);
		rvk_frame_finish(r);
		for (int i = 0; i < 2; i++)
			set_free(r, &r->sets[i]);
		rvk_image_free(r, &r->colour);
		rvk_image_free(r, &r->depth);
		rvk_buffer_free(r, &r->readback);
		if (r->draw_fence)
			vkDestroyFence(r->dev, r->draw_fence, NULL);
		if (r->sampler_clamp)
			vkDestroySampler(r->dev, r->sampler_clamp, NULL);
		if (r->sampler_wrap_u)
			vkDestroySampler(r->dev, r->sampler_wrap_u, NULL);
		if (r->pool)
			vkDestroyCommandPool(r->dev, r->pool, NULL);
		vkDestroyDevice(r->dev, NULL);
	}
	if (r->instance)
		vkDestroyInstance(r->instance, NULL);
	free(r);
}

const char *rvk_device_name(const struct rvk *r)
{
	return r ? r->device_name : "";
}

/* Upload --------------------------------------------------------------------------- */

static const float stand_in_texel[4] = { 0.0f, 0.0f, 0.0f, 1.0f };

/* Where each table of u lies and how it is stored; an absent table gets a
 * one-texel stand-in (no light, full transmittance). */
static void find_tables(const struct rvk_upload *u, const void *ret_src[RVK_TABLES],
			struct rvk_table_layout ret[RVK_TABLES], uint32_t ret_changed[RVK_TABLES])
{
	static const uint32_t ids[RVK_AERIAL] = { SKY_TABLE_TRANSMITTANCE, SKY_TABLE_SKYVIEW,
						  SKY_TABLE_MULTISCATTER, SKY_TABLE_CLOUD, SKY_TABLE_SHADOW };
	uint64_t off = 0;
	for (int i = 0; i < RVK_TABLES; i++) {
		int k = i - RVK_AERIAL;
		const struct sky_gpu_table *t = i < RVK_AERIAL ? &u->tables[ids[i]] :
						(uint32_t)k < u->n_aerial ? u->aerial[k] : NULL;
		struct rvk_table_layout *l = &ret[i];
		memset(l, 0, sizeof(*l));
		if (t && t->present && t->texels) {
			l->format = t->format;
			l->width = t->width;
			l->height = t->height;
			/* The shadow table's slice 0, the sun's map, as a 2-D image. */
			l->depth = i == RVK_SHADOW ? 1 : t->depth;
			ret_src[i] = t->texels;
			ret_changed[i] = t->changed_generation;
		} else {
			l->width = l->height = l->depth = 1;
			ret_src[i] = stand_in_texel;
			ret_changed[i] = UINT32_MAX;
		}
		l->bytes = (uint64_t)l->width * l->height * l->depth *
			   (l->format == SKY_FORMAT_RGBA16F ? 8 : 16);
		l->staging_offset = off;
		off += (l->bytes + 63) & ~(uint64_t)63;
	}
}

static VkFormat vk_format(uint32_t format)
{
	return format == SKY_FORMAT_RGBA16F ? VK_FORMAT_R16G16B16A16_SFLOAT :
					      VK_FORMAT_R32G32B32A32_SFLOAT;
}

/* (Re)creates the set's images and staging buffer where the layout changed. */
static int set_reshape(struct rvk *r, struct rvk_set *s, const struct rvk_table_layout l[RVK_TABLES],
		       char *err, size_t err_size)
{
	bool changed = !s->ubo.buf;
	int rc = 0;
	for (int i = 0; i < RVK_TABLES; i++) {
		struct rvk_image *im = &s->tables[i];
		if (im->image && im->format == vk_format(l[i].format) && im->width == l[i].width &&
		    im->height == l[i].height && im->depth == l[i].depth)
			continue;
		rvk_image_free(r, im);
		s->layout[i].uploaded_generation = 0;
		rc = rvk_image_new(r, i >= RVK_AERIAL ? VK_IMAGE_TYPE_3D : VK_IMAGE_TYPE_2D,
				   vk_format(l[i].format), l[i].width, l[i].height, l[i].depth,
				   VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
				   VK_IMAGE_ASPECT_COLOR_BIT, im, err, err_size);
		if (rc < 0)
			return rc;
		changed = true;
	}
	uint64_t need = l[RVK_TABLES - 1].staging_offset + l[RVK_TABLES - 1].bytes;
	if (s->staging.bytes < need) {
		rvk_buffer_free(r, &s->staging);
		if ((rc = rvk_buffer_new(r, need, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true, &s->staging,
					 err, err_size)) < 0)
			return rc;
	}
	if (!s->ubo.buf && (rc = rvk_buffer_new(r, sizeof(struct rvk_frame_ubo),
						VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true, &s->ubo,
						err, err_size)) < 0)
		return rc;
	return changed ? rvk_frame_bind_set(r, s, err, err_size) : 0;
}

static void vec4(float d[4], const double v[3], double w)
{
	d[0] = (float)v[0];
	d[1] = (float)v[1];
	d[2] = (float)v[2];
	d[3] = (float)w;
}

/* The wall camera's basis, as sky_render's perspective camera (roll 0). */
static void camera_basis(const struct rvk_camera *c, double f[3], double rt[3], double u[3])
{
	double yaw = c->yaw_deg * DEG, pitch = c->pitch_deg * DEG;
	skysample_direction(pitch, yaw, f);
	rt[0] = cos(yaw);
	rt[1] = -sin(yaw);
	rt[2] = 0.0;
	u[0] = rt[1] * f[2] - rt[2] * f[1];
	u[1] = rt[2] * f[0] - rt[0] * f[2];
	u[2] = rt[0] * f[1] - rt[1] * f[0];
}

/* The clouds' part of the block: the slot's layers as
 * skycloud_scene_from_slot reads them, and the sun with its map's frame
 * where the slot holds one (else 4 steps toward it). */
static void fill_clouds(const struct rvk *r, const struct rvk_upload *up, bool has_map,
			struct rvk_frame_ubo *u)
{
	struct skycloud_layer layers[SKYCLOUD_MAX_LAYERS];
	struct skycloud_scene sc;
	struct skycloud_shadow_frame f;
	if (!up->clouds || r->opt.cloud_steps <= 0 || skycloud_scene_from_slot(up->clouds, layers, &sc) == 0)
		return;
	for (int i = 0; i < sc.n_layers; i++) {
		u->layers[i].l = layers[i];
		u->scene[0][i] = (float)sc.phase_g[i];
		u->scene[1][i] = (float)sc.albedo[i];
	}
	u->scene[2][0] = (float)sc.octaves;
	u->scene[2][1] = (float)sc.octave_a;
	u->scene[2][2] = (float)sc.octave_b;
	u->scene[2][3] = (float)sc.octave_c;
	u->scene[3][0] = sc.offset_km[0];
	u->scene[3][1] = sc.offset_km[1];
	u->scene[3][2] = (float)sc.n_layers;
	u->scene[3][3] = (float)sc.extent_km;
	vec4(u->scene[4], up->ambient_lx, sc.diffusion);
	u->scene[5][0] = (float)sc.table_shift_km[0];
	u->scene[5][1] = (float)sc.table_shift_km[1];
	has_map = has_map && (up->clouds->shadow_lights & 1u);
	for (int c = 0; c < 4; c++) {
		u->sun[0][c] = up->state[0]->sun[c];
		u->sun[1][c] = up->state[0]->sun_illuminance_lx[c];
	}
	u->sun[0][3] = has_map ? 1.0f : 0.0f;
	u->sun[1][3] = 0.0f;
	skycloud_shadow_frame_from_slot(up->clouds, 0, &f);
	vec4(u->sun[2], f.row_u, f.row_u[3]);
	vec4(u->sun[3], f.row_v, f.row_v[3]);
	vec4(u->sun[4], f.row_depth, f.row_depth[3]);
	u->clouds[0] = (float)r->opt.cloud_steps;
	u->clouds[1] = has_map ? 0.0f : 4.0f;
}

static void fill_ubo(const struct rvk *r, const struct rvk_upload *up, struct rvk_frame_ubo *u)
{
	const struct rvk_camera *c = &r->opt.camera;
	double f[3], rt[3], upv[3];
	double wall_w = (double)c->cols * c->width, wall_h = (double)c->rows * c->height;

	memset(u, 0, sizeof(*u));
	for (uint32_t k = 0; k < RVK_MAX_AERIAL; k++)
		u->sky[k] = *up->state[k < up->n_aerial ? k : 0];
	camera_basis(c, f, rt, upv);
	u->wall[0] = (float)wall_w;
	u->wall[1] = (float)wall_h;
	u->wall[2] = (float)c->col * c->width;
	u->wall[3] = (float)c->row * c->height;
	u->tile[0] = (float)c->width;
	u->tile[1] = (float)c->height;
	u->tile[2] = (float)c->projection;
	u->tile[3] = (float)tan(0.5 * c->vfov_deg * DEG);
	vec4(u->cam_f, f, c->yaw_deg * DEG);
	vec4(u->cam_r, rt, wall_w / wall_h);
	vec4(u->cam_u, upv, 1e-4);	/* near plane: 10 cm */
	vec4(u->ambient_lx, up->ambient_lx, r->opt.disk_flags);
	double albedo[3] = { r->opt.terrain_albedo, r->opt.terrain_albedo, r->opt.terrain_albedo };
	vec4(u->terrain, albedo, up->n_aerial);
	const struct sky_gpu_table *sh = &up->tables[SKY_TABLE_SHADOW];
	fill_clouds(r, up, sh->present && sh->texels && sh->depth >= 2, u);
}

static void image_barrier(VkCommandBuffer cmd, VkImage image, VkImageLayout from, VkImageLayout to,
			  VkAccessFlags src_access, VkAccessFlags dst_access,
			  VkPipelineStageFlags src_stage, VkPipelineStageFlags dst_stage,
			  VkImageAspectFlags aspect)
{
	VkImageMemoryBarrier b = { .sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER,
		.srcAccessMask = src_access, .dstAccessMask = dst_access, .oldLayout = from,
		.newLayout = to, .srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
		.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED, .image = image,
		.subresourceRange = { aspect, 0, 1, 0, 1 } };
	vkCmdPipelineBarrier(cmd, src_stage, dst_stage, 0, 0, NULL, 0, NULL, 1, &b);
}

static int record_upload(struct rvk *r, struct rvk_set *s, char *err, size_t err_size)
{
	VkCommandBufferBeginInfo bi = { .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
		.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT };
	int rc = 0;
	VK_TRY(vkResetCommandBuffer(s->upload_cmd, 0));
	VK_TRY(vkBeginCommandBuffer(s->upload_cmd, &bi));
	for (int i = 0; i < RVK_TABLES; i++) {
		const struct rvk_table_layout *l = &s->layout[i];
		VkImage im = s->tables[i].image;
		if (!l->copy)
			continue;
		image_barrier(s->upload_cmd, im, VK_IMAGE_LAYOUT_UNDEFINED,
			      VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
			      VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
			      VK_IMAGE_ASPECT_COLOR_BIT);
		VkBufferImageCopy copy = { .bufferOffset = l->staging_offset,
			.imageSubresource = { VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1 },
			.imageExtent = { l->width, l->height, l->depth } };
		vkCmdCopyBufferToImage(s->upload_cmd, s->staging.buf, im,
				       VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &copy);
		image_barrier(s->upload_cmd, im, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
			      VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT,
			      VK_ACCESS_SHADER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
			      VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_IMAGE_ASPECT_COLOR_BIT);
	}
	VK_TRY(vkEndCommandBuffer(s->upload_cmd));
	return 0;
fail:
	return rc;
}

/* Waits for the set's upload, if one runs, and forgets it. */
static int set_settle(struct rvk *r, struct rvk_set *s, char *err, size_t err_size)
{
	int rc = 0;
	if (!s->uploading)
		return 0;
	VK_TRY(vkWaitForFences(r->dev, 1, &s->upload_fence, VK_TRUE, UINT64_MAX));
	VK_TRY(vkResetFences(r->dev, 1, &s->upload_fence));
	s->uploading = false;
	return 0;
fail:
	return rc;
}

int rvk_upload(struct rvk *r, const struct rvk_upload *u, char *err, size_t err_size)
{
	if (!r || !u || !u->tables || !u->n_aerial || u->n_aerial > RVK_MAX_AERIAL)
		return -EINVAL;
	for (uint32_t k = 0; k < u->n_aerial; k++)
		if (!u->state[k])
			return -EINVAL;
	struct rvk_set *s = &r->sets[r->active == 0 ? 1 : 0];
	const void *src[RVK_TABLES];
	struct rvk_table_layout l[RVK_TABLES];
	uint32_t changed[RVK_TABLES];
	int rc = set_settle(r, s, err, err_size);

	if (rc < 0)
		return rc;
	find_tables(u, src, l, changed);
	if ((rc = set_reshape(r, s, l, err, err_size)) < 0)
		return rc;
	for (int i = 0; i < RVK_TABLES; i++) {
		l[i].uploaded_generation = s->layout[i].uploaded_generation;
		l[i].from_view = i >= RVK_AERIAL && u->aerial_is_view[i - RVK_AERIAL];
		l[i].copy = l[i].uploaded_generation != changed[i] || changed[i] == UINT32_MAX ||
			    l[i].from_view != s->layout[i].from_view;
		if (l[i].copy)
			memcpy((unsigned char *)s->staging.map + l[i].staging_offset, src[i], l[i].bytes);
		l[i].uploaded_generation = changed[i];
	}
	memcpy(s->layout, l, sizeof(l));
	fill_ubo(r, u, s->ubo.map);
	s->generation = u->generation;
	if ((rc = record_upload(r, s, err, err_size)) < 0)
		return rc;
	VkSubmitInfo si = { .sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1,
		.pCommandBuffers = &s->upload_cmd };
	VK_TRY(vkQueueSubmit(r->queue, 1, &si, s->upload_fence));
	s->uploading = true;
	return 0;
fail:
	return rc;
}

void rvk_cancel_upload(struct rvk *r)
{
	if (!r)
		return;
	struct rvk_set *s = &r->sets[r->active == 0 ? 1 : 0];
	char err[8];
	if (s->uploading)
		set_settle(r, s, err, sizeof(err));
	/* What it copied may be torn: every table goes up again next time. */
	for (int i = 0; i < RVK_TABLES; i++)
		s->layout[i].uploaded_generation = 0;
}

void rvk_forget_tables(struct rvk *r)
{
	for (int k = 0; r && k < 2; k++)
		for (int i = 0; i < RVK_TABLES; i++)
			r->sets[k].layout[i].uploaded_generation = 0;
}

/* Draw --------------------------------------------------------------------------- */

/* Makes a finished upload the drawn set; before the first frame, waits for it. */
static int take_upload(struct rvk *r, char *err, size_t err_size)
{
	struct rvk_set *s = &r->sets[r->active == 0 ? 1 : 0];
	int rc = 0;
	if (!s->uploading)
		return 0;
	if (r->active >= 0) {
		VkResult vr = vkGetFenceStatus(r->dev, s->upload_fence);
		if (vr == VK_NOT_READY)
			return 0;
		VK_TRY(vr);
	}
	if ((rc = set_settle(r, s, err, err_size)) < 0)
		return rc;
	r->active = (int)(s - r->sets);
	return 0;
fail:
	return rc;
}

int rvk_draw(struct rvk *r, const float **ret_rgba, uint64_t *ret_generation, char *err,
	     size_t err_size)
{
	if (!r || !ret_rgba || !ret_generation)
		return -EINVAL;
	int rc = take_upload(r, err, err_size);
	if (rc < 0)
		return rc;
	if (r->active < 0) {
		rvk_set_err(err, err_size, "no tables uploaded yet");
		return -EAGAIN;
	}
	const struct rvk_set *s = &r->sets[r->active];
	if ((rc = rvk_frame_record(r, s, err, err_size)) < 0)
		return rc;
	VkSubmitInfo si = { .sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1,
		.pCommandBuffers = &r->draw_cmd };
	VK_TRY(vkQueueSubmit(r->queue, 1, &si, r->draw_fence));
	VK_TRY(vkWaitForFences(r->dev, 1, &r->draw_fence, VK_TRUE, UINT64_MAX));
	VK_TRY(vkResetFences(r->dev, 1, &r->draw_fence));
	*ret_rgba = r->readback.map;
	*ret_generation = s->generation;
	return 0;
fail:
	return rc;
}
