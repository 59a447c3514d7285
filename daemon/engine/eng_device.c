/* eng_device.c - the engine's device: the Vulkan loader and instance, the
 * choice of device, its memory and buffers, the descriptor set, and the
 * waiter thread that makes the ordered pipelines and turns the fence into
 * an eventfd. */
#include "eng_internal.h"

#include <dlfcn.h>
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include "shaders.h"

void eng_set_err(char *err, size_t n, const char *fmt, ...)
{
	va_list ap;
	if (!err || !n)
		return;
	va_start(ap, fmt);
	vsnprintf(err, n, fmt, ap);
	va_end(ap);
}

/* Loader and instance ------------------------------------------------------ */

static int load_loader(struct vkfn *vk, void **ret_handle, char *err, size_t err_size)
{
	void *h = dlopen("libvulkan.so.1", RTLD_NOW | RTLD_LOCAL);
	if (!h)
		h = dlopen("libvulkan.so", RTLD_NOW | RTLD_LOCAL);
	if (!h) {
		eng_set_err(err, err_size,
			"no Vulkan loader (libvulkan.so.1): install the Debian package libvulkan1 "
			"(and mesa-vulkan-drivers for lavapipe)");
		return -ENOENT;
	}
	vk->vkGetInstanceProcAddr = (PFN_vkGetInstanceProcAddr)dlsym(h, "vkGetInstanceProcAddr");
	if (!vk->vkGetInstanceProcAddr) {
		dlclose(h);
		eng_set_err(err, err_size, "libvulkan.so.1 has no vkGetInstanceProcAddr: broken loader");
		return -ENOENT;
	}
#define LOAD_GLOBAL(name) vk->name = (PFN_##name)vk->vkGetInstanceProcAddr(NULL, #name);
	VKFN_GLOBAL(LOAD_GLOBAL)
#undef LOAD_GLOBAL
	*ret_handle = h;
	return 0;
}

static int load_instance_fns(struct vkfn *vk, VkInstance inst, char *err, size_t err_size)
{
#define LOAD_INSTANCE(name)                                                          \
	vk->name = (PFN_##name)vk->vkGetInstanceProcAddr(inst, #name);               \
	if (!vk->name) {                                                             \
		eng_set_err(err, err_size, "Vulkan loader lacks %s (Vulkan 1.1 needed)", #name); \
		return -ENOSYS;                                                      \
	}
	VKFN_INSTANCE(LOAD_INSTANCE)
#undef LOAD_INSTANCE
	return 0;
}

static int create_instance(struct vkfn *vk, VkInstance *ret, char *err, size_t err_size)
{
	VkApplicationInfo app = { .sType = VK_STRUCTURE_TYPE_APPLICATION_INFO,
		.pApplicationName = "skyd", .apiVersion = VK_API_VERSION_1_1 };
	VkInstanceCreateInfo ci = { .sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
		.pApplicationInfo = &app };
	const char *ext[1];
	uint32_t n = 0;
	int rc = 0;

	/* Portability enumeration lists non-conformant drivers too, where present. */
	if (vk->vkEnumerateInstanceExtensionProperties(NULL, &n, NULL) == VK_SUCCESS && n) {
		VkExtensionProperties *props = calloc(n, sizeof(*props));
		if (props && vk->vkEnumerateInstanceExtensionProperties(NULL, &n, props) == VK_SUCCESS)
			for (uint32_t i = 0; i < n; i++)
				if (!strcmp(props[i].extensionName,
					    VK_KHR_PORTABILITY_ENUMERATION_EXTENSION_NAME)) {
					ext[0] = VK_KHR_PORTABILITY_ENUMERATION_EXTENSION_NAME;
					ci.enabledExtensionCount = 1;
					ci.ppEnabledExtensionNames = ext;
					ci.flags |= VK_INSTANCE_CREATE_ENUMERATE_PORTABILITY_BIT_KHR;
				}
		free(props);
	}
	/* No driver at all is the machine's lack, like a missing loader
	 * (-ENODEV: tests skip); any other failure is the driver's. */
	VkResult r = vk->vkCreateInstance(&ci, NULL, ret);
	if (r == VK_ERROR_INCOMPATIBLE_DRIVER) {
		eng_set_err(err, err_size,
			"cannot create a Vulkan instance: no driver; install mesa-vulkan-drivers "
			"(lavapipe) or your GPU's Vulkan driver");
		return -ENODEV;
	}
	VK_TRY(r);
	return load_instance_fns(vk, *ret, err, err_size);
fail:
	return rc;
}

static const char *type_name(VkPhysicalDeviceType t)
{
	switch (t) {
	case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete";
	case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated";
	case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual";
	case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
	default: return "other";
	}
}

static int type_rank(int t)
{
	switch (t) {
	case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 4;
	case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 3;
	case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
	case VK_PHYSICAL_DEVICE_TYPE_CPU: return 1;
	default: return 0;
	}
}

static void describe(struct vkfn *vk, VkPhysicalDevice pd, uint32_t index, struct eng_device *ret)
{
	VkPhysicalDeviceDriverProperties drv = { .sType =
		VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES };
	VkPhysicalDeviceProperties2 p2 = { .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2,
		.pNext = &drv };
	VkPhysicalDeviceProperties p;

	vk->vkGetPhysicalDeviceProperties(pd, &p);
	memset(ret, 0, sizeof(*ret));
	ret->index = index;
	ret->type = p.deviceType;
	ret->vendor_id = p.vendorID;
	ret->device_id = p.deviceID;
	snprintf(ret->name, sizeof(ret->name), "%s", p.deviceName);
	snprintf(ret->type_name, sizeof(ret->type_name), "%s", type_name(p.deviceType));
	if (p.apiVersion >= VK_API_VERSION_1_2) {
		vk->vkGetPhysicalDeviceProperties2(pd, &p2);
		snprintf(ret->driver, sizeof(ret->driver), "%s %s", drv.driverName, drv.driverInfo);
	} else {
		snprintf(ret->driver, sizeof(ret->driver), "driver %u", p.driverVersion);
	}
}

static int enumerate(struct vkfn *vk, VkInstance inst, VkPhysicalDevice **ret, uint32_t *ret_n,
		     char *err, size_t err_size)
{
	uint32_t n = 0;
	int rc = 0;
	VkPhysicalDevice *pds = NULL;

	VK_TRY(vk->vkEnumeratePhysicalDevices(inst, &n, NULL));
	pds = calloc(n ? n : 1, sizeof(*pds));
	if (!pds)
		return -ENOMEM;
	VK_TRY(vk->vkEnumeratePhysicalDevices(inst, &n, pds));
	*ret = pds;
	*ret_n = n;
	return 0;
fail:
	free(pds);
	return rc;
}

int eng_list_devices(struct eng_device *ret, size_t max, char *err, size_t err_size)
{
	struct vkfn vk = { 0 };
	void *loader = NULL;
	VkInstance inst = VK_NULL_HANDLE;
	VkPhysicalDevice *pds = NULL;
	uint32_t n = 0;
	int rc = load_loader(&vk, &loader, err, err_size);

	if (rc < 0)
		return rc;
	rc = create_instance(&vk, &inst, err, err_size);
	if (rc == 0)
		rc = enumerate(&vk, inst, &pds, &n, err, err_size);
	if (rc == 0) {
		for (uint32_t i = 0; i < n && i < max; i++)
			describe(&vk, pds[i], i, &ret[i]);
		rc = (int)n;
	}
	free(pds);
	if (inst)
		vk.vkDestroyInstance(inst, NULL);
	dlclose(loader);
	return rc;
}

/* Picks a device: selector (or $SKYD_DEVICE) as an index or a name substring,
 * else the best type. */
static int pick_device(struct eng *e, const char *selector, char *err, size_t err_size)
{
	VkPhysicalDevice *pds = NULL;
	uint32_t n = 0;
	int rc = enumerate(&e->vk, e->instance, &pds, &n, err, err_size), best = -1;

	if (rc < 0)
		return rc;
	if (n == 0) {
		free(pds);
		eng_set_err(err, err_size,
			"no Vulkan device found: install mesa-vulkan-drivers (lavapipe) or a GPU driver");
		return -ENODEV;
	}
	if (!selector || !*selector)
		selector = getenv("SKYD_DEVICE");
	struct eng_device d;
	if (selector && *selector) {
		char *end;
		unsigned long idx = strtoul(selector, &end, 10);
		for (uint32_t i = 0; i < n && best < 0; i++) {
			describe(&e->vk, pds[i], i, &d);
			if ((!*end && idx == i) || strcasestr(d.name, selector))
				best = (int)i;
		}
		if (best < 0) {
			free(pds);
			eng_set_err(err, err_size, "device '%s': no such Vulkan device (see skyd --list-devices)",
				selector);
			return -ENODEV;
		}
	} else {
		int best_rank = -1;
		for (uint32_t i = 0; i < n; i++) {
			describe(&e->vk, pds[i], i, &d);
			if (type_rank(d.type) > best_rank) {
				best_rank = type_rank(d.type);
				best = (int)i;
			}
		}
	}
	e->phys = pds[best];
	describe(&e->vk, e->phys, (uint32_t)best, &e->info);
	free(pds);
	return 0;
}

/* Device objects ------------------------------------------------------------ */

void eng_buffer_free(struct eng *e, struct gpu_buffer *b)
{
	if (b->buf)
		e->vk.vkDestroyBuffer(e->dev, b->buf, NULL);
	if (b->mem)
		e->vk.vkFreeMemory(e->dev, b->mem, NULL);	/* unmaps implicitly */
	memset(b, 0, sizeof(*b));
}

int eng_buffer_new(struct eng *e, VkDeviceSize bytes, VkBufferUsageFlags usage,
		      VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer,
		      struct gpu_buffer *ret, char *err, size_t err_size)
{
	struct gpu_buffer b = { .bytes = bytes };
	VkBufferCreateInfo bi = { .sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO, .size = bytes,
		.usage = usage, .sharingMode = VK_SHARING_MODE_EXCLUSIVE };
	VkMemoryRequirements req;
	int rc = 0;

	VK_TRY(e->vk.vkCreateBuffer(e->dev, &bi, NULL, &b.buf));
	e->vk.vkGetBufferMemoryRequirements(e->dev, b.buf, &req);
	int type = vkcheck_find_memory(&e->mem_props, req.memoryTypeBits, want, prefer);
	if (type < 0) {
		eng_set_err(err, err_size, "no Vulkan memory type with flags 0x%x", want);
		rc = -ENOMEM;
		goto fail;
	}
	VkMemoryAllocateInfo ai = { .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
		.allocationSize = req.size, .memoryTypeIndex = (uint32_t)type };
	VK_TRY(e->vk.vkAllocateMemory(e->dev, &ai, NULL, &b.mem));
	VK_TRY(e->vk.vkBindBufferMemory(e->dev, b.buf, b.mem, 0));
	/* Mapped where host-visible memory was asked for, or preferred and got. */
	if (((want | prefer) & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) &&
	    (e->mem_props.memoryTypes[type].propertyFlags & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT))
		VK_TRY(e->vk.vkMapMemory(e->dev, b.mem, 0, VK_WHOLE_SIZE, 0, &b.map));
	*ret = b;
	return 0;
fail:
	eng_buffer_free(e, &b);
	return rc;
}

/* An internal float32 vec4 buffer that one pass writes (storage) and later
 * passes read through a texel view (the column densities, the moments). */
void eng_vec4_buffer_free(struct eng *e, struct gpu_buffer *b, VkBufferView *view)
{
	if (*view)
		e->vk.vkDestroyBufferView(e->dev, *view, NULL);
	*view = VK_NULL_HANDLE;
	eng_buffer_free(e, b);
}

int eng_vec4_buffer_new(struct eng *e, VkDeviceSize bytes, struct gpu_buffer *ret, VkBufferView *ret_view,
			   char *err, size_t err_size)
{
	int rc = eng_buffer_new(e, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT,
			    VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, ret, err, err_size);
	if (rc < 0)
		return rc;
	VkBufferViewCreateInfo vi = { .sType = VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO, .buffer = ret->buf,
		.format = VK_FORMAT_R32G32B32A32_SFLOAT, .range = VK_WHOLE_SIZE };
	VK_TRY(e->vk.vkCreateBufferView(e->dev, &vi, NULL, ret_view));
	return 0;
fail:
	eng_vec4_buffer_free(e, ret, ret_view);
	return rc;
}

static void *waiter_main(void *arg)
{
	struct eng *e = arg;

	pthread_mutex_lock(&e->lock);
	for (;;) {
		while (!e->pending && !e->quit)
			pthread_cond_wait(&e->cond, &e->lock);
		if (e->quit)
			break;
		bool compiling = e->compiling;
		pthread_mutex_unlock(&e->lock);
		VkResult r = compiling ? eng_make_orders(e)
				       : e->vk.vkWaitForFences(e->dev, 1, &e->fence, VK_TRUE, UINT64_MAX);
		pthread_mutex_lock(&e->lock);
		e->wait_result = r;
		e->pending = false;
		e->finished = true;
		uint64_t one = 1;
		if (write(e->event_fd, &one, sizeof(one)) < 0) {
			/* The counter cannot overflow at one write per computation. */
		}
	}
	pthread_mutex_unlock(&e->lock);
	return NULL;
}

VkDescriptorType eng_binding_type(int binding)
{
	if (binding == 0 || binding == BINDING_MULTISCATTER_UBO)
		return VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
	if (binding == BINDING_MOMENT_TEX || binding == BINDING_COLUMNS_TEX || binding == BINDING_AERIAL_TEX ||
	    binding == BINDING_CLOUD_TEX || binding == BINDING_SHADOW_TEX)
		return VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
	if (binding == BINDING_TRANSMITTANCE_IMG || binding == BINDING_MULTISCATTER_IMG)
		return VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
	return binding <= STATE_N_TABLES || binding >= BINDING_VIEWS
		       ? VK_DESCRIPTOR_TYPE_STORAGE_BUFFER
		       : VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
}

/* Whether the device offers extension name. */
static bool device_has(struct eng *e, const char *name)
{
	uint32_t n = 0;
	bool found = false;

	if (e->vk.vkEnumerateDeviceExtensionProperties(e->phys, NULL, &n, NULL) != VK_SUCCESS || !n)
		return false;
	VkExtensionProperties *p = calloc(n, sizeof(*p));
	if (p && e->vk.vkEnumerateDeviceExtensionProperties(e->phys, NULL, &n, p) == VK_SUCCESS)
		for (uint32_t i = 0; i < n && !found; i++)
			found = !strcmp(p[i].extensionName, name);
	free(p);
	return found;
}

/* The device's limits and memory, and the queue family the engine uses:
 * one with compute, one without graphics if there is one (it runs beside
 * rendering). */
static int choose_queue(struct eng *e, char *err, size_t err_size)
{
	VkPhysicalDeviceProperties props;
	uint32_t nq = 0;

	e->vk.vkGetPhysicalDeviceProperties(e->phys, &props);
	e->limits = props.limits;
	VkPhysicalDeviceExternalMemoryHostPropertiesEXT host = { .sType =
		VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_EXTERNAL_MEMORY_HOST_PROPERTIES_EXT };
	VkPhysicalDeviceSubgroupProperties sub = { .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES,
		.pNext = device_has(e, VK_EXT_EXTERNAL_MEMORY_HOST_EXTENSION_NAME) ? &host : NULL };
	VkPhysicalDeviceProperties2 p2 = { .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2,
		.pNext = &sub };
	e->vk.vkGetPhysicalDeviceProperties2(e->phys, &p2);
	e->subgroup_size = sub.subgroupSize;
	e->import_alignment = host.minImportedHostPointerAlignment;
	e->timestamp_period_ns = props.limits.timestampPeriod;
	e->vk.vkGetPhysicalDeviceMemoryProperties(e->phys, &e->mem_props);
	e->vk.vkGetPhysicalDeviceQueueFamilyProperties(e->phys, &nq, NULL);
	VkQueueFamilyProperties *qf = calloc(nq ? nq : 1, sizeof(*qf));
	if (!qf)
		return -ENOMEM;
	e->vk.vkGetPhysicalDeviceQueueFamilyProperties(e->phys, &nq, qf);
	e->queue_family = UINT32_MAX;
	for (uint32_t i = 0; i < nq; i++)
		if (qf[i].queueFlags & VK_QUEUE_COMPUTE_BIT) {
			if (e->queue_family == UINT32_MAX || !(qf[i].queueFlags & VK_QUEUE_GRAPHICS_BIT))
				e->queue_family = i;
		}
	if (e->queue_family != UINT32_MAX)
		e->timestamps = qf[e->queue_family].timestampValidBits > 0 &&
				e->timestamp_period_ns > 0;
	free(qf);
	if (e->queue_family == UINT32_MAX) {
		eng_set_err(err, err_size, "device '%s' has no compute queue", e->info.name);
		return -ENODEV;
	}
	return 0;
}

/* The one descriptor set, its layout and the pipelines' layout. */
static int create_descriptors(struct eng *e, char *err, size_t err_size)
{
	VkDescriptorSetLayoutBinding b[N_BINDINGS];
	int rc = 0;

	for (int i = 0; i < N_BINDINGS; i++)
		b[i] = (VkDescriptorSetLayoutBinding){ .binding = (uint32_t)i,
			.descriptorType = eng_binding_type(i), .descriptorCount = 1,
			.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT };
	VkDescriptorSetLayoutCreateInfo li = { .sType =
		VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO, .bindingCount = N_BINDINGS,
		.pBindings = b };
	VK_TRY(e->vk.vkCreateDescriptorSetLayout(e->dev, &li, NULL, &e->set_layout));
	VkPipelineLayoutCreateInfo pli = { .sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
		.setLayoutCount = 1, .pSetLayouts = &e->set_layout };
	VK_TRY(e->vk.vkCreatePipelineLayout(e->dev, &pli, NULL, &e->pipe_layout));
	/* The pool holds the set's descriptors, counted by type. */
	VkDescriptorPoolSize ps[4] = { { VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 0 },
		{ VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 0 }, { VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, 0 },
		{ VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 0 } };
	for (int i = 0; i < N_BINDINGS; i++)
		for (int k = 0; k < 4; k++)
			ps[k].descriptorCount += ps[k].type == b[i].descriptorType;
	VkDescriptorPoolCreateInfo dpi = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
		.maxSets = 1, .poolSizeCount = 4, .pPoolSizes = ps };
	VK_TRY(e->vk.vkCreateDescriptorPool(e->dev, &dpi, NULL, &e->desc_pool));
	VkDescriptorSetAllocateInfo dai = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
		.descriptorPool = e->desc_pool, .descriptorSetCount = 1, .pSetLayouts = &e->set_layout };
	VK_TRY(e->vk.vkAllocateDescriptorSets(e->dev, &dai, &e->set));
fail:
	return rc;
}

/* The host-visible buffers the engine writes before each computation: the
 * uniform block, the aerial jobs and the pack pass's counts. */
static int create_host_buffers(struct eng *e, char *err, size_t err_size)
{
	const VkMemoryPropertyFlags host =
		VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
	int rc = eng_buffer_new(e, sizeof(struct gpu_params), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT,
				host, 0, &e->params, err, err_size);

	if (rc == 0)
		rc = eng_buffer_new(e, VIEW_BUFFER_BYTES, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, host, 0,
				    &e->views, err, err_size);
	if (rc == 0)
		rc = eng_buffer_new(e, sizeof(struct gpu_pack),
				    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
				    host, 0, &e->pack, err, err_size);
	if (rc == 0)
		memset(e->pack.map, 0, sizeof(struct gpu_pack));
	return rc;
}

static int create_device(struct eng *e, char *err, size_t err_size)
{
	int rc = choose_queue(e, err, err_size);

	if (rc < 0)
		return rc;
	float prio = 1.0f;
	VkDeviceQueueCreateInfo qi = { .sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
		.queueFamilyIndex = e->queue_family, .queueCount = 1, .pQueuePriorities = &prio };
	/* Imported host memory lets the device write the published slot
	 * itself (eng_host.c); its minImportedHostPointerAlignment was read
	 * with the limits. */
	const char *ext[] = { VK_EXT_EXTERNAL_MEMORY_HOST_EXTENSION_NAME };
	e->host_import = e->import_alignment > 0;
	VkDeviceCreateInfo di = { .sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
		.queueCreateInfoCount = 1, .pQueueCreateInfos = &qi,
		.enabledExtensionCount = e->host_import ? 1 : 0, .ppEnabledExtensionNames = ext };
	VK_TRY(e->vk.vkCreateDevice(e->phys, &di, NULL, &e->dev));
#define LOAD_DEVICE(name)                                                       \
	e->vk.name = (PFN_##name)e->vk.vkGetDeviceProcAddr(e->dev, #name);      \
	if (!e->vk.name) {                                                      \
		eng_set_err(err, err_size, "Vulkan device lacks %s", #name);        \
		return -ENOSYS;                                                 \
	}
	VKFN_DEVICE(LOAD_DEVICE)
#undef LOAD_DEVICE
	if (e->host_import)
		e->get_host_pointer_props = (PFN_vkGetMemoryHostPointerPropertiesEXT)e->vk.vkGetDeviceProcAddr(
			e->dev, "vkGetMemoryHostPointerPropertiesEXT");
	e->host_import = e->get_host_pointer_props != NULL;
	e->vk.vkGetDeviceQueue(e->dev, e->queue_family, 0, &e->queue);
	rc = create_descriptors(e, err, err_size);
	if (rc < 0)
		return rc;

	for (int t = 0; t < SHADER_COUNT; t++) {
		VkShaderModuleCreateInfo si = { .sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO,
			.codeSize = shader_code[t].bytes, .pCode = shader_code[t].words };
		VK_TRY(e->vk.vkCreateShaderModule(e->dev, &si, NULL, &e->modules[t]));
	}
	VkCommandPoolCreateInfo cpi = { .sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
		.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
		.queueFamilyIndex = e->queue_family };
	VK_TRY(e->vk.vkCreateCommandPool(e->dev, &cpi, NULL, &e->cmd_pool));
	VkCommandBufferAllocateInfo cai = { .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
		.commandPool = e->cmd_pool, .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
		.commandBufferCount = 1 };
	VK_TRY(e->vk.vkAllocateCommandBuffers(e->dev, &cai, &e->cmd));
	if (e->timestamps) {
		VkQueryPoolCreateInfo qpi = { .sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO,
			.queryType = VK_QUERY_TYPE_TIMESTAMP, .queryCount = 2 * N_PASSES };
		VK_TRY(e->vk.vkCreateQueryPool(e->dev, &qpi, NULL, &e->queries));
	}
	VkFenceCreateInfo fi = { .sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO };
	VK_TRY(e->vk.vkCreateFence(e->dev, &fi, NULL, &e->fence));
	/* Texel coordinates (a table's texel i at i + 0.5), bilinear, clamped:
	 * the hand-made bilinear() of common.glsl, by the texture units. */
	VkSamplerCreateInfo sci = { .sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO,
		.magFilter = VK_FILTER_LINEAR, .minFilter = VK_FILTER_LINEAR,
		.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST,
		.addressModeU = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
		.addressModeV = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
		.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE, .unnormalizedCoordinates = VK_TRUE };
	VK_TRY(e->vk.vkCreateSampler(e->dev, &sci, NULL, &e->sampler));
	rc = create_host_buffers(e, err, err_size);
fail:
	return rc;
}

int eng_new(const char *selector, char *err, size_t err_size, struct eng **ret)
{
	struct eng *e = calloc(1, sizeof(*e));
	int rc;

	if (!e)
		return -ENOMEM;
	e->event_fd = -1;
	e->share_views = true;
	pthread_mutex_init(&e->lock, NULL);
	pthread_cond_init(&e->cond, NULL);
	rc = load_loader(&e->vk, &e->loader, err, err_size);
	if (rc == 0)
		rc = create_instance(&e->vk, &e->instance, err, err_size);
	if (rc == 0)
		rc = pick_device(e, selector, err, err_size);
	if (rc == 0)
		rc = create_device(e, err, err_size);
	if (rc == 0)
		eng_grain_choose(e);
	if (rc == 0) {
		e->event_fd = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
		if (e->event_fd < 0)
			rc = -errno;
	}
	if (rc == 0) {
		rc = -pthread_create(&e->waiter, NULL, waiter_main, e);
		e->waiter_started = rc == 0;
	}
	if (rc < 0) {
		eng_free(e);
		return rc;
	}
	*ret = e;
	return 0;
}

void eng_free(struct eng *e)
{
	if (!e)
		return;
	if (e->waiter_started) {
		pthread_mutex_lock(&e->lock);
		e->quit = true;
		pthread_cond_signal(&e->cond);
		pthread_mutex_unlock(&e->lock);
		/* The waiter may be inside vkWaitForFences: the GPU finishes first. */
		pthread_join(e->waiter, NULL);
	}
	if (e->dev) {
		e->vk.vkDeviceWaitIdle(e->dev);
		eng_save_cache(e);
		if (e->pipeline_cache)
			e->vk.vkDestroyPipelineCache(e->dev, e->pipeline_cache, NULL);
		eng_host_free(e);
		eng_free_tables(e);
		eng_free_pipelines(e);
		for (int t = 0; t < SHADER_COUNT; t++)
			if (e->modules[t])
				e->vk.vkDestroyShaderModule(e->dev, e->modules[t], NULL);
		eng_buffer_free(e, &e->params);
		eng_buffer_free(e, &e->views);
		eng_buffer_free(e, &e->pack);
		if (e->fence)
			e->vk.vkDestroyFence(e->dev, e->fence, NULL);
		if (e->sampler)
			e->vk.vkDestroySampler(e->dev, e->sampler, NULL);
		if (e->queries)
			e->vk.vkDestroyQueryPool(e->dev, e->queries, NULL);
		if (e->cmd_pool)
			e->vk.vkDestroyCommandPool(e->dev, e->cmd_pool, NULL);
		if (e->desc_pool)
			e->vk.vkDestroyDescriptorPool(e->dev, e->desc_pool, NULL);
		if (e->pipe_layout)
			e->vk.vkDestroyPipelineLayout(e->dev, e->pipe_layout, NULL);
		if (e->set_layout)
			e->vk.vkDestroyDescriptorSetLayout(e->dev, e->set_layout, NULL);
		e->vk.vkDestroyDevice(e->dev, NULL);
	}
	if (e->instance)
		e->vk.vkDestroyInstance(e->instance, NULL);
	if (e->loader)
		dlclose(e->loader);
	if (e->event_fd >= 0)
		close(e->event_fd);
	pthread_cond_destroy(&e->cond);
	pthread_mutex_destroy(&e->lock);
	free(e->cache_path);
	free(e);
}
