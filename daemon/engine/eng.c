/* eng.c - the LUT engine: Vulkan compute passes for the four sky tables. */
#include "eng.h"

#include <dlfcn.h>
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/eventfd.h>
#include <time.h>
#include <unistd.h>

#include "phase.h"
#include "shaders.h"
#include "skymap.h"
#include "vkfn.h"

#define MAX_PIPELINES 32	/* cached variants per pass */
#define N_SPEC 24
/* Texels of a row one invocation shares its rays between: sun angles of
 * multi-scattering, azimuths of sky-view. 12 azimuths took the time-of-day
 * change from 35.0-36.3 to 34.1-34.9 % of a full recompute against 8 once
 * the ground's phase term added to each step (skybench demand, three
 * paired runs each); 16 was slower in session 2 (register pressure). */
#define MS_SUN_GROUP 4
#define SV_AZ_GROUP 12
/* The state's camera and STATE_MAX_VIEWS views, 3 vec4 each. */
#define VIEW_BUFFER_BYTES ((1 + STATE_MAX_VIEWS) * 3 * 4 * sizeof(float))

/* The uniform block of shaders/common.glsl, std140: vec4s only. */
struct gpu_constituent {
	float scattering[4], absorption[4], layer0[4], layer0c_1[4], layer1c[4];
};
/* The tables later passes look up: transmittance and multi-scattering. */
#define N_LOOKUPS 2
/* Bindings: 0 parameters, 1-4 the tables (storage), 5-6 the lookups,
 * 7 the cameras of the aerial volumes (storage), 8 the column densities of
 * the transmittance texels (storage), 9 the scratch of the iteration of
 * psi_ms (storage: the next table, then L2). */
#define VIEWS_BINDING (1 + STATE_N_TABLES + N_LOOKUPS)
#define COLUMNS_BINDING (VIEWS_BINDING + 1)
#define ITERATE_BINDING (COLUMNS_BINDING + 1)
/* 10 the shape of the multiply scattered light (storage, written by the
 * multi-scattering pass, rescaled by the iteration), 11 the same memory as
 * a lookup. */
#define MOMENT_BINDING (ITERATE_BINDING + 1)
#define MOMENT_TEX_BINDING (MOMENT_BINDING + 1)
/* 12 the column densities again, as a lookup: the delta-M passes read
 * them at every step (a texel buffer read cost half a storage read). */
#define COLUMNS_TEX_BINDING (MOMENT_TEX_BINDING + 1)
#define N_BINDINGS (COLUMNS_TEX_BINDING + 1)
/* Compute passes: one per table, then the column densities (SHADER_COLUMNS)
 * and the iteration of psi_ms (SHADER_MSITERATE). */
#define PASS_COLUMNS STATE_N_TABLES
#define PASS_MSITERATE (STATE_N_TABLES + 1)
#define N_PASSES (STATE_N_TABLES + 2)

struct gpu_params {
	float planet[4], albedo[4], sun_dir[4], sun_illum[4], moon_dir[4], moon_illum[4];
	float cam_fwd[4], cam_right[4], cam_up[4], misc[4];
	struct gpu_constituent c[ATMO_MAX_CONSTITUENTS];
	float night[4];		/* night-sky floor, after the constituents as in common.glsl */
	/* The ground's first bounce through each constituent's phase, k - 1
	 * of the view's cos-zenith as a polynomial (phase_ground_fit), a vec4
	 * of the constituents per coefficient. */
	float ground_fit[PHASE_GROUND_FIT][4];
	/* Delta-M's forward peak (phase_delta_peak): h, its spread in rad. */
	float delta_peak[4];
};

/* phase_ground_excess of one constituent, kept while its phase stays: it
 * costs about 30000 phase evaluations, more than a sun change's tables. */
struct ground_cache {
	bool valid;
	enum atmo_phase kind;
	double g;
	double fit[PHASE_GROUND_FIT];	/* phase_ground_fit of phase_ground_excess */
	double legendre[2];	/* phase_legendre, l = 1 and 2: a quadrature too */
};

/* Specialization constants, by constant_id. */
struct spec {
	int32_t v[N_SPEC];
};

struct pipeline {
	struct spec key;
	VkPipeline pipe;
};

struct gpu_buffer {
	VkBuffer buf;
	VkDeviceMemory mem;
	void *map;		/* host-visible buffers only */
	VkDeviceSize bytes;
};

/* What the column densities depend on: the shell's geometry, the density
 * profiles of the constituents in the shaders, the table's size and steps
 * (the column pass's specialization). Coefficients are not in it. */
struct column_key {
	float planet[3];	/* bottom, top, shell: the observer left out */
	float h_top;		/* misc.w */
	float layers[ATMO_MAX_CONSTITUENTS][12];
	struct spec spec;
};

struct eng {
	struct vkfn vk;
	void *loader;
	VkInstance instance;
	VkPhysicalDevice phys;
	struct eng_device info;
	VkPhysicalDeviceMemoryProperties mem_props;
	VkPhysicalDeviceLimits limits;
	uint32_t queue_family;
	float timestamp_period_ns;
	bool timestamps;
	VkDevice dev;
	VkQueue queue;
	VkDescriptorSetLayout set_layout;
	VkPipelineLayout pipe_layout;
	VkDescriptorPool desc_pool;
	VkDescriptorSet set;
	VkShaderModule modules[N_PASSES];
	struct pipeline pipes[N_PASSES][MAX_PIPELINES];
	int n_pipes[N_PASSES];
	uint64_t pipelines_created;
	VkCommandPool cmd_pool;
	VkCommandBuffer cmd;
	VkQueryPool queries;
	VkFence fence;

	struct gpu_buffer params;
	struct gpu_buffer views;			/* 3 vec4 per aerial volume */
	struct gpu_buffer table[STATE_N_TABLES];	/* device memory */
	struct gpu_buffer readback[STATE_N_TABLES];	/* host memory */
	size_t table_bytes[STATE_N_TABLES];
	/* Transmittance and multi-scattering are read by the later passes
	 * through texel buffers: the sampler's gathers are vectorized, where a
	 * storage-buffer load with a varying index is a loop over the lanes on
	 * lavapipe (measured: about half of the sky-view pass). */
	VkBufferView lookup_view[N_LOOKUPS];
	VkFormat lookup_format[N_LOOKUPS];
	/* Column densities per transmittance texel (vec4, one per constituent):
	 * recomputed only when column_key changes, so that a change of the
	 * coefficients alone runs the tiny transmittance pass only. */
	struct gpu_buffer columns;
	/* The shape of the multiply scattered light, an RGBA float32 texel
	 * per multi-scattering texel (ms_source in common.glsl). */
	struct gpu_buffer moment;
	VkBufferView moment_view;
	VkBufferView columns_view;	/* COLUMNS_TEX_BINDING */
	struct ground_cache ground[ATMO_MAX_CONSTITUENTS];	/* by gpu constituent */
	struct ground_cache delta;	/* fill_delta's: the truncated phase's fit, f and g' in legendre */
	struct column_key column_key;
	bool columns_valid;
	bool columns_in_flight;
	/* The iteration of psi_ms (shaders/msiterate.comp): its output in the
	 * table's format, copied over the table after each step, then L2 as
	 * float32 RGBA per texel. */
	struct gpu_buffer ms_iterate;
	uint32_t iterations_in_flight;

	/* Completion: a waiter thread waits on the fence, then writes the eventfd. */
	int event_fd;
	pthread_t waiter;
	bool waiter_started;
	pthread_mutex_t lock;
	pthread_cond_t cond;
	bool pending, finished, quit;
	VkResult wait_result;
	uint32_t in_flight_mask;
	struct timespec submit_time;
};

static void set_err(char *err, size_t n, const char *fmt, ...)
{
	va_list ap;
	if (!err || !n)
		return;
	va_start(ap, fmt);
	vsnprintf(err, n, fmt, ap);
	va_end(ap);
}

static const char *vk_result_name(VkResult r)
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

/* Every Vulkan call goes through VK_TRY: on failure it names the call and
 * the result in err and jumps to the function's one cleanup label. */
#define VK_TRY(call)                                                                 \
	do {                                                                         \
		VkResult vk_r_ = (call);                                             \
		if (vk_r_ != VK_SUCCESS) {                                           \
			set_err(err, err_size, "%s failed: %s (%d) at eng.c:%d", #call,   \
				vk_result_name(vk_r_), (int)vk_r_, __LINE__);              \
			rc = vk_r_ == VK_ERROR_OUT_OF_HOST_MEMORY ? -ENOMEM : -EIO;  \
			goto fail;                                                   \
		}                                                                    \
	} while (0)

static double elapsed_ms(const struct timespec *a, const struct timespec *b)
{
	return (b->tv_sec - a->tv_sec) * 1e3 + (b->tv_nsec - a->tv_nsec) * 1e-6;
}

/* Loader and instance ------------------------------------------------------ */

static int load_loader(struct vkfn *vk, void **ret_handle, char *err, size_t err_size)
{
	void *h = dlopen("libvulkan.so.1", RTLD_NOW | RTLD_LOCAL);
	if (!h)
		h = dlopen("libvulkan.so", RTLD_NOW | RTLD_LOCAL);
	if (!h) {
		set_err(err, err_size,
			"no Vulkan loader (libvulkan.so.1): install the Debian package libvulkan1 "
			"(and mesa-vulkan-drivers for lavapipe)");
		return -ENOENT;
	}
	vk->vkGetInstanceProcAddr = (PFN_vkGetInstanceProcAddr)dlsym(h, "vkGetInstanceProcAddr");
	if (!vk->vkGetInstanceProcAddr) {
		dlclose(h);
		set_err(err, err_size, "libvulkan.so.1 has no vkGetInstanceProcAddr: broken loader");
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
		set_err(err, err_size, "Vulkan loader lacks %s (Vulkan 1.1 needed)", #name); \
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
	VK_TRY(vk->vkCreateInstance(&ci, NULL, ret));
	return load_instance_fns(vk, *ret, err, err_size);
fail:
	if (rc == -EIO)
		set_err(err, err_size,
			"cannot create a Vulkan instance: no driver; install mesa-vulkan-drivers "
			"(lavapipe) or your GPU's Vulkan driver");
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
		set_err(err, err_size,
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
			set_err(err, err_size, "device '%s': no such Vulkan device (see skyd --list-devices)",
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

static int find_memory(struct eng *e, uint32_t type_bits, VkMemoryPropertyFlags want,
		       VkMemoryPropertyFlags prefer)
{
	int fallback = -1;
	for (uint32_t i = 0; i < e->mem_props.memoryTypeCount; i++) {
		VkMemoryPropertyFlags f = e->mem_props.memoryTypes[i].propertyFlags;
		if (!(type_bits & (1u << i)) || (f & want) != want)
			continue;
		if ((f & prefer) == prefer)
			return (int)i;
		if (fallback < 0)
			fallback = (int)i;
	}
	return fallback;
}

static void buffer_free(struct eng *e, struct gpu_buffer *b)
{
	if (b->buf)
		e->vk.vkDestroyBuffer(e->dev, b->buf, NULL);
	if (b->mem)
		e->vk.vkFreeMemory(e->dev, b->mem, NULL);	/* unmaps implicitly */
	memset(b, 0, sizeof(*b));
}

static int buffer_new(struct eng *e, VkDeviceSize bytes, VkBufferUsageFlags usage,
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
	int type = find_memory(e, req.memoryTypeBits, want, prefer);
	if (type < 0) {
		set_err(err, err_size, "no Vulkan memory type with flags 0x%x", want);
		rc = -ENOMEM;
		goto fail;
	}
	VkMemoryAllocateInfo ai = { .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
		.allocationSize = req.size, .memoryTypeIndex = (uint32_t)type };
	VK_TRY(e->vk.vkAllocateMemory(e->dev, &ai, NULL, &b.mem));
	VK_TRY(e->vk.vkBindBufferMemory(e->dev, b.buf, b.mem, 0));
	if (want & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT)
		VK_TRY(e->vk.vkMapMemory(e->dev, b.mem, 0, VK_WHOLE_SIZE, 0, &b.map));
	*ret = b;
	return 0;
fail:
	buffer_free(e, &b);
	return rc;
}

/* An internal float32 vec4 buffer that one pass writes (storage) and later
 * passes read through a texel view (the column densities, the moments). */
static void vec4_buffer_free(struct eng *e, struct gpu_buffer *b, VkBufferView *view)
{
	if (*view)
		e->vk.vkDestroyBufferView(e->dev, *view, NULL);
	*view = VK_NULL_HANDLE;
	buffer_free(e, b);
}

static int vec4_buffer_new(struct eng *e, VkDeviceSize bytes, struct gpu_buffer *ret, VkBufferView *ret_view,
			   char *err, size_t err_size)
{
	int rc = buffer_new(e, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT,
			    VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, ret, err, err_size);
	if (rc < 0)
		return rc;
	VkBufferViewCreateInfo vi = { .sType = VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO, .buffer = ret->buf,
		.format = VK_FORMAT_R32G32B32A32_SFLOAT, .range = VK_WHOLE_SIZE };
	VK_TRY(e->vk.vkCreateBufferView(e->dev, &vi, NULL, ret_view));
	return 0;
fail:
	vec4_buffer_free(e, ret, ret_view);
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
		pthread_mutex_unlock(&e->lock);
		VkResult r = e->vk.vkWaitForFences(e->dev, 1, &e->fence, VK_TRUE, UINT64_MAX);
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

static VkDescriptorType binding_type(int binding)
{
	if (binding == 0)
		return VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
	if (binding == MOMENT_TEX_BINDING || binding == COLUMNS_TEX_BINDING)
		return VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
	return binding <= STATE_N_TABLES || binding >= VIEWS_BINDING
		       ? VK_DESCRIPTOR_TYPE_STORAGE_BUFFER
		       : VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
}

static int create_device(struct eng *e, char *err, size_t err_size)
{
	VkPhysicalDeviceProperties props;
	uint32_t nq = 0;
	int rc = 0;

	e->vk.vkGetPhysicalDeviceProperties(e->phys, &props);
	e->limits = props.limits;
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
			/* Prefer a compute queue without graphics: it runs beside rendering. */
			if (e->queue_family == UINT32_MAX || !(qf[i].queueFlags & VK_QUEUE_GRAPHICS_BIT))
				e->queue_family = i;
		}
	if (e->queue_family != UINT32_MAX)
		e->timestamps = qf[e->queue_family].timestampValidBits > 0 &&
				e->timestamp_period_ns > 0;
	free(qf);
	if (e->queue_family == UINT32_MAX) {
		set_err(err, err_size, "device '%s' has no compute queue", e->info.name);
		return -ENODEV;
	}

	float prio = 1.0f;
	VkDeviceQueueCreateInfo qi = { .sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
		.queueFamilyIndex = e->queue_family, .queueCount = 1, .pQueuePriorities = &prio };
	VkDeviceCreateInfo di = { .sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
		.queueCreateInfoCount = 1, .pQueueCreateInfos = &qi };
	VK_TRY(e->vk.vkCreateDevice(e->phys, &di, NULL, &e->dev));
#define LOAD_DEVICE(name)                                                       \
	e->vk.name = (PFN_##name)e->vk.vkGetDeviceProcAddr(e->dev, #name);      \
	if (!e->vk.name) {                                                      \
		set_err(err, err_size, "Vulkan device lacks %s", #name);        \
		return -ENOSYS;                                                 \
	}
	VKFN_DEVICE(LOAD_DEVICE)
#undef LOAD_DEVICE
	e->vk.vkGetDeviceQueue(e->dev, e->queue_family, 0, &e->queue);

	VkDescriptorSetLayoutBinding b[N_BINDINGS];
	for (int i = 0; i < N_BINDINGS; i++)
		b[i] = (VkDescriptorSetLayoutBinding){ .binding = (uint32_t)i,
			.descriptorType = binding_type(i), .descriptorCount = 1,
			.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT };
	VkDescriptorSetLayoutCreateInfo li = { .sType =
		VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO, .bindingCount = N_BINDINGS,
		.pBindings = b };
	VK_TRY(e->vk.vkCreateDescriptorSetLayout(e->dev, &li, NULL, &e->set_layout));
	VkPipelineLayoutCreateInfo pli = { .sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
		.setLayoutCount = 1, .pSetLayouts = &e->set_layout };
	VK_TRY(e->vk.vkCreatePipelineLayout(e->dev, &pli, NULL, &e->pipe_layout));
	VkDescriptorPoolSize ps[3] = { { VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1 },
		{ VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, STATE_N_TABLES + 4 },
		{ VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, N_LOOKUPS + 2 } };
	VkDescriptorPoolCreateInfo dpi = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
		.maxSets = 1, .poolSizeCount = 3, .pPoolSizes = ps };
	VK_TRY(e->vk.vkCreateDescriptorPool(e->dev, &dpi, NULL, &e->desc_pool));
	VkDescriptorSetAllocateInfo dai = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
		.descriptorPool = e->desc_pool, .descriptorSetCount = 1, .pSetLayouts = &e->set_layout };
	VK_TRY(e->vk.vkAllocateDescriptorSets(e->dev, &dai, &e->set));

	for (int t = 0; t < N_PASSES; t++) {
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
	rc = buffer_new(e, sizeof(struct gpu_params), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT,
			VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT, 0,
			&e->params, err, err_size);
	if (rc == 0)
		rc = buffer_new(e, VIEW_BUFFER_BYTES, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
				VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
				0, &e->views, err, err_size);
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
	pthread_mutex_init(&e->lock, NULL);
	pthread_cond_init(&e->cond, NULL);
	rc = load_loader(&e->vk, &e->loader, err, err_size);
	if (rc == 0)
		rc = create_instance(&e->vk, &e->instance, err, err_size);
	if (rc == 0)
		rc = pick_device(e, selector, err, err_size);
	if (rc == 0)
		rc = create_device(e, err, err_size);
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
		for (int i = 0; i < N_LOOKUPS; i++)
			if (e->lookup_view[i])
				e->vk.vkDestroyBufferView(e->dev, e->lookup_view[i], NULL);
		for (int t = 0; t < N_PASSES; t++) {
			if (t < STATE_N_TABLES) {
				buffer_free(e, &e->table[t]);
				buffer_free(e, &e->readback[t]);
			}
			for (int i = 0; i < e->n_pipes[t]; i++)
				e->vk.vkDestroyPipeline(e->dev, e->pipes[t][i].pipe, NULL);
			if (e->modules[t])
				e->vk.vkDestroyShaderModule(e->dev, e->modules[t], NULL);
		}
		buffer_free(e, &e->params);
		buffer_free(e, &e->views);
		vec4_buffer_free(e, &e->columns, &e->columns_view);
		buffer_free(e, &e->ms_iterate);
		vec4_buffer_free(e, &e->moment, &e->moment_view);
		if (e->fence)
			e->vk.vkDestroyFence(e->dev, e->fence, NULL);
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
	free(e);
}

const struct eng_device *eng_device(const struct eng *e)
{
	return &e->info;
}

uint64_t eng_max_table_bytes(const struct eng *e)
{
	return e->limits.maxStorageBufferRange;
}

void eng_f16_range(const struct eng *e, const struct sky_state *s, uint32_t mask,
		   struct eng_f16_range *ret)
{
	memset(ret, 0, sizeof(*ret));
	if (s->quality.storage != STATE_F16)
		return;
	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t bytes;
		const uint16_t *h = eng_table(e, (enum state_table)t, &bytes);
		if (!(mask & STATE_BIT(t)) || !h)
			continue;
		for (size_t i = 0; i < bytes / 8; i++) {
			for (int c = 0; c < 3; c++) {
				uint16_t exponent = (h[4 * i + c] >> 10) & 0x1f;
				uint16_t mantissa = h[4 * i + c] & 0x3ff;
				if (exponent == 0x1f)
					ret->overflow++;
				else if (exponent == 0 && mantissa != 0 && t >= STATE_SKYVIEW)
					ret->subnormal++;
			}
		}
		if (t >= STATE_SKYVIEW)
			ret->radiance_values += 3 * (bytes / 8);
	}
}

int eng_f16_broken(const struct eng_f16_range *r)
{
	return r->overflow > 0 || r->subnormal * 100 > r->radiance_values;
}

uint64_t eng_pipelines_created(const struct eng *e)
{
	return e->pipelines_created;
}

int eng_event_fd(const struct eng *e)
{
	return e->event_fd;
}

void eng_forget_columns(struct eng *e)
{
	e->columns_valid = false;
}

const void *eng_table(const struct eng *e, enum state_table t, size_t *ret_bytes)
{
	if (ret_bytes)
		*ret_bytes = e->table_bytes[t];
	return e->readback[t].map;
}

/* Parameters and specialization --------------------------------------------- */

static bool constituent_active(const struct atmo_constituent *c)
{
	for (int i = 0; i < 3; i++)
		if (c->scattering_per_km[i] > 0.0 || c->absorption_per_km[i] > 0.0)
			return true;
	return false;
}

static bool constituent_scatters(const struct atmo_constituent *c)
{
	return c->scattering_per_km[0] > 0 || c->scattering_per_km[1] > 0 || c->scattering_per_km[2] > 0;
}

static void put4(float d[4], double a, double b, double c, double w)
{
	d[0] = (float)a;
	d[1] = (float)b;
	d[2] = (float)c;
	d[3] = (float)w;
}

static void fill_delta(struct eng *e, const struct sky_state *s, int delta, struct gpu_params *p,
		       struct spec *base);

static void fill_params(struct eng *e, const struct sky_state *s, struct gpu_params *p, struct spec *base)
{
	const struct atmo *a = &s->atmo;
	double sun[3], moon[3], fwd[3], right[3], up[3];
	double h0 = s->altitude_km > 0.0 ? s->altitude_km : 0.0;
	double shell = a->top_radius_km - a->bottom_radius_km;

	memset(p, 0, sizeof(*p));
	memset(base, 0, sizeof(*base));
	put4(p->planet, a->bottom_radius_km, a->top_radius_km, shell, h0);
	put4(p->albedo, a->ground_albedo[0], a->ground_albedo[1], a->ground_albedo[2], 0);
	state_direction(s->sun.elevation_deg, s->sun.azimuth_deg, sun);
	state_direction(s->moon.elevation_deg, s->moon.azimuth_deg, moon);
	put4(p->sun_dir, sun[0], sun[1], sun[2], s->sun.angular_radius_deg * SKYMAP_PI / 180.0);
	put4(p->moon_dir, moon[0], moon[1], moon[2], s->moon.angular_radius_deg * SKYMAP_PI / 180.0);
	put4(p->sun_illum, s->sun.illuminance_lx * s->sun.color[0],
	     s->sun.illuminance_lx * s->sun.color[1], s->sun.illuminance_lx * s->sun.color[2], 0);
	put4(p->moon_illum, s->moon.illuminance_lx * s->moon.color[0],
	     s->moon.illuminance_lx * s->moon.color[1], s->moon.illuminance_lx * s->moon.color[2], 0);
	state_camera_basis(&s->camera, fwd, right, up);
	put4(p->cam_fwd, fwd[0], fwd[1], fwd[2], tan(s->camera.vfov_deg * SKYMAP_PI / 360.0));
	put4(p->cam_right, right[0], right[1], right[2], s->camera.aspect);
	put4(p->cam_up, up[0], up[1], up[2], s->quality.aerial_range_km);
	put4(p->misc, skymap_horizon_cos(a->bottom_radius_km, h0), s->quality.skyview_min_steps,
	     s->quality.aerial_spacing == STATE_SQUARED ? 1.0 : 0.0,
	     sqrt(shell * (2.0 * a->bottom_radius_km + shell)));

	double night_cd_m2, night_gain;
	state_night_floor(s, &night_cd_m2, &night_gain);
	put4(p->night, night_cd_m2, night_cd_m2, night_cd_m2, night_gain);

	/* Constituents that are zero everywhere are left out of the shaders. */
	double g1[ATMO_MAX_CONSTITUENTS] = { 0 };	/* by index in a */
	int n = 0;
	for (int i = 0; i < a->n_constituents; i++) {
		const struct atmo_constituent *c = &a->c[i];
		if (!constituent_active(c))
			continue;
		struct gpu_constituent *g = &p->c[n];
		const struct atmo_layer *l0 = &c->density.layers[0], *l1 = &c->density.layers[1];
		put4(g->scattering, c->scattering_per_km[0], c->scattering_per_km[1],
		     c->scattering_per_km[2], c->g);
		struct ground_cache *gc = &e->ground[n];
		enum atmo_phase kind = constituent_scatters(c) ? c->phase : ATMO_PHASE_NONE;
		if (!gc->valid || gc->kind != kind || gc->g != c->g) {
			double excess[PHASE_GROUND_N];
			phase_ground_excess(kind, c->g, excess);
			phase_ground_fit(excess, gc->fit);
			gc->legendre[0] = phase_legendre(kind, c->g, 1);
			gc->legendre[1] = phase_legendre(kind, c->g, 2);
			gc->valid = true;
			gc->kind = kind;
			gc->g = c->g;
		}
		g1[i] = gc->legendre[0];
		put4(g->absorption, c->absorption_per_km[0], c->absorption_per_km[1],
		     c->absorption_per_km[2], gc->legendre[0]);
		put4(g->layer0, l0->width_km, l0->exp_term, l0->exp_scale_per_km, l0->linear_per_km);
		put4(g->layer0c_1, l0->constant, l1->exp_term, l1->exp_scale_per_km, l1->linear_per_km);
		put4(g->layer1c, l1->constant, gc->legendre[1], 0, 0);
		/* A constituent that scatters nothing needs no phase function. */
		base->v[1 + n] = constituent_scatters(c) ? (int32_t)c->phase : 0;
		for (int k = 0; k < PHASE_GROUND_FIT; k++)
			p->ground_fit[k][n] = (float)gc->fit[k];
		/* Profiles without an exponential term (ozone's tent) skip exp(). */
		if (l0->exp_term != 0.0 || l1->exp_term != 0.0)
			base->v[18] |= 1 << n;
		n++;
	}
	base->v[0] = n;
	base->v[5] = s->quality.storage == STATE_F16;
	base->v[6] = s->moon.illuminance_lx > 0.0;
	base->v[7] = a->ground_albedo[0] == 0 && a->ground_albedo[1] == 0 && a->ground_albedo[2] == 0;
	base->v[8] = (int32_t)s->quality.t[STATE_TRANSMITTANCE].width;
	base->v[9] = (int32_t)s->quality.t[STATE_TRANSMITTANCE].height;
	base->v[10] = (int32_t)s->quality.t[STATE_MULTISCATTER].width;
	base->v[11] = (int32_t)s->quality.t[STATE_MULTISCATTER].height;
	/* multiscatter_dirs=0 switches the higher orders off: sky-view and
	 * aerial perspective drop the term, and the multi-scattering table, if
	 * asked for at all, is computed with the cheapest quadrature. */
	base->v[16] = s->quality.multiscatter_dirs ? (int32_t)s->quality.multiscatter_dirs : 2;
	base->v[17] = s->quality.multiscatter_dirs != 0;
	/* The lobe constituent (common.glsl's ms_source) by its index among those in the shaders, plus 1. */
	int delta = s->quality.multiscatter_dirs ? phase_delta_constituent(s, g1) : -1;
	int lobe = s->quality.multiscatter_dirs ? phase_lobe_constituent(s, g1) : -1;
	if (lobe >= 0 && constituent_active(&a->c[lobe])) {
		int before = 0;
		for (int i = 0; i < lobe; i++)
			before += constituent_active(&a->c[i]);
		base->v[22] = before + 1;
	}
	fill_delta(e, s, delta, p, base);
}

/* Delta-M for the higher orders (common.glsl's delta_source): the
 * constituent's index among those in the shaders plus 1 in constant 23,
 * its forward fraction f and the truncated phase's g' in layer1c.zw, and
 * the ground's first bounce through the truncated phase, which is what
 * scatters psi_ms in the scaled medium. Kept while the phase stays (a
 * quadrature and 30000 phase evaluations, more than a sun change's tables). */
static void fill_delta(struct eng *e, const struct sky_state *s, int delta, struct gpu_params *p,
		       struct spec *base)
{
	const struct atmo *a = &s->atmo;
	if (delta < 0 || !constituent_active(&a->c[delta]))
		return;
	int n = 0;
	for (int i = 0; i < delta; i++)
		n += constituent_active(&a->c[i]);
	struct ground_cache *dc = &e->delta;
	if (!dc->valid || dc->kind != a->c[delta].phase || dc->g != a->c[delta].g) {
		double excess[PHASE_GROUND_N];
		phase_delta_truncation(a->c[delta].phase, a->c[delta].g, &dc->legendre[0], &dc->legendre[1]);
		phase_ground_excess(ATMO_PHASE_HENYEY_GREENSTEIN, dc->legendre[1], excess);
		phase_ground_fit(excess, dc->fit);
		dc->valid = true;
		dc->kind = a->c[delta].phase;
		dc->g = a->c[delta].g;
	}
	for (int k = 0; k < PHASE_GROUND_FIT; k++)
		p->ground_fit[k][n] = (float)dc->fit[k];
	p->c[n].layer1c[2] = (float)dc->legendre[0];
	p->c[n].layer1c[3] = (float)dc->legendre[1];
	double h, spread;
	phase_delta_peak(a->c[delta].phase, a->c[delta].g, &h, &spread);
	put4(p->delta_peak, h, spread, 0, 0);
	base->v[23] = n + 1;
}

/* The cameras of the aerial volumes: the state's, then each view's. */
static void fill_views(const struct sky_state *s, float *out)
{
	double h0 = s->altitude_km > 0.0 ? s->altitude_km : 0.0;
	double fwd[3], right[3], up[3];

	for (uint32_t i = 0; i <= s->n_views; i++) {
		const struct state_camera *c = i ? &s->views[i - 1].camera : &s->camera;
		double h = i && !isnan(s->views[i - 1].altitude_km) ? s->views[i - 1].altitude_km : h0;
		state_camera_basis(c, fwd, right, up);
		put4(out + 12 * i, fwd[0], fwd[1], fwd[2], tan(c->vfov_deg * SKYMAP_PI / 360.0));
		put4(out + 12 * i + 4, right[0], right[1], right[2], c->aspect);
		put4(out + 12 * i + 8, up[0], up[1], up[2], h > 0.0 ? h : 0.0);
	}
}

/* The constants one pass is specialized on: the others are zeroed so that a
 * change that does not concern a pass reuses its cached pipeline. */
static struct spec pass_spec(const struct spec *base, const struct sky_state *s, int t)
{
	struct spec k = *base;
	const struct state_table_quality *q = &s->quality.t[t];

	k.v[12] = (int32_t)q->width;
	k.v[13] = (int32_t)q->height;
	k.v[14] = (int32_t)q->depth;
	k.v[15] = (int32_t)q->steps;
	if (t == STATE_TRANSMITTANCE) {
		k.v[1] = k.v[2] = k.v[3] = k.v[4] = 0;	/* extinction only */
		k.v[6] = k.v[7] = 0;
		k.v[10] = k.v[11] = k.v[16] = 0;
		k.v[15] = k.v[18] = 0;	/* steps and profiles: the column pass's */
	}
	if (t != STATE_MULTISCATTER)
		k.v[16] = 0;
	k.v[19] = t == STATE_MULTISCATTER ? MS_SUN_GROUP : 0;
	k.v[20] = t == STATE_SKYVIEW ? SV_AZ_GROUP : 0;
	if (t == STATE_MULTISCATTER)
		k.v[6] = k.v[17] = 0;	/* the table is the term itself */
	if (t == STATE_TRANSMITTANCE)
		k.v[17] = k.v[22] = k.v[23] = 0;
	if (t == STATE_SKYVIEW || t == STATE_AERIAL)
		k.v[7] = 0;	/* the ground enters through the multiscatter table */
	return k;
}

/* The column pass is specialized on the constituents' count and profile
 * kinds, the transmittance table's size and its steps, nothing else. */
static struct spec column_spec(const struct spec *base, const struct sky_state *s)
{
	const struct state_table_quality *q = &s->quality.t[STATE_TRANSMITTANCE];
	struct spec k = { { 0 } };

	k.v[0] = base->v[0];
	k.v[12] = (int32_t)q->width;
	k.v[13] = (int32_t)q->height;
	k.v[15] = (int32_t)q->steps;
	k.v[18] = base->v[18];
	return k;
}

static void column_key(const struct gpu_params *p, const struct spec *column_spec,
		       struct column_key *ret)
{
	memset(ret, 0, sizeof(*ret));
	memcpy(ret->planet, p->planet, sizeof(ret->planet));
	ret->h_top = p->misc[3];
	for (int i = 0; i < column_spec->v[0]; i++) {
		memcpy(ret->layers[i], p->c[i].layer0, 4 * sizeof(float));
		memcpy(ret->layers[i] + 4, p->c[i].layer0c_1, 4 * sizeof(float));
		memcpy(ret->layers[i] + 8, p->c[i].layer1c, 4 * sizeof(float));
	}
	ret->spec = *column_spec;
}

static int get_pipeline(struct eng *e, int t, const struct spec *key, VkPipeline *ret,
			char *err, size_t err_size)
{
	int rc = 0;
	for (int i = 0; i < e->n_pipes[t]; i++)
		if (!memcmp(&e->pipes[t][i].key, key, sizeof(*key))) {
			*ret = e->pipes[t][i].pipe;
			return 0;
		}
	if (e->n_pipes[t] == MAX_PIPELINES) {
		/* Evict the oldest variant; no work is in flight here. */
		e->vk.vkDestroyPipeline(e->dev, e->pipes[t][0].pipe, NULL);
		memmove(&e->pipes[t][0], &e->pipes[t][1], sizeof(e->pipes[t][0]) * (MAX_PIPELINES - 1));
		e->n_pipes[t]--;
	}
	VkSpecializationMapEntry map[N_SPEC];
	for (uint32_t i = 0; i < N_SPEC; i++)
		map[i] = (VkSpecializationMapEntry){ i, i * 4, 4 };
	/* constant_id 16 is declared only in the multiscatter shader; unused
	 * entries are ignored by Vulkan. */
	VkSpecializationInfo si = { N_SPEC, map, sizeof(key->v), key->v };
	VkComputePipelineCreateInfo ci = { .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
		.stage = { .sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
			   .stage = VK_SHADER_STAGE_COMPUTE_BIT, .module = e->modules[t],
			   .pName = "main", .pSpecializationInfo = &si },
		.layout = e->pipe_layout };
	VkPipeline p;
	VK_TRY(e->vk.vkCreateComputePipelines(e->dev, VK_NULL_HANDLE, 1, &ci, NULL, &p));
	e->pipelines_created++;
	e->pipes[t][e->n_pipes[t]].key = *key;
	e->pipes[t][e->n_pipes[t]].pipe = p;
	e->n_pipes[t]++;
	*ret = p;
fail:
	return rc;
}

/* (Re)allocates the tables whose size changed; returns the mask of tables
 * that must be recomputed because their contents were lost. */
static int ensure_tables(struct eng *e, const struct sky_state *s, uint32_t *ret_lost,
			 char *err, size_t err_size)
{
	VkFormat format = s->quality.storage == STATE_F16 ? VK_FORMAT_R16G16B16A16_SFLOAT
							 : VK_FORMAT_R32G32B32A32_SFLOAT;
	uint32_t lost = 0;
	bool rebind = false;
	int rc = 0;

	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t bytes = state_table_bytes(s, (enum state_table)t);
		if (t == STATE_AERIAL)
			bytes *= 1 + s->n_views;
		if (e->table[t].buf && e->table_bytes[t] == bytes &&
		    (t >= N_LOOKUPS || e->lookup_format[t] == format))
			continue;
		if (t < N_LOOKUPS && e->lookup_view[t]) {
			e->vk.vkDestroyBufferView(e->dev, e->lookup_view[t], NULL);
			e->lookup_view[t] = VK_NULL_HANDLE;
		}
		buffer_free(e, &e->table[t]);
		buffer_free(e, &e->readback[t]);
		e->table_bytes[t] = 0;
		rc = buffer_new(e, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
					  VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
					  VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
				VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, &e->table[t], err, err_size);
		if (rc == 0)
			rc = buffer_new(e, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
					VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT,
					VK_MEMORY_PROPERTY_HOST_CACHED_BIT, &e->readback[t], err, err_size);
		if (rc < 0)
			return rc;
		if (t < N_LOOKUPS) {
			VkBufferViewCreateInfo vi = { .sType = VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO,
				.buffer = e->table[t].buf, .format = format, .range = VK_WHOLE_SIZE };
			VK_TRY(e->vk.vkCreateBufferView(e->dev, &vi, NULL, &e->lookup_view[t]));
			e->lookup_format[t] = format;
		}
		memset(e->readback[t].map, 0, bytes);
		e->table_bytes[t] = bytes;
		lost |= STATE_BIT(t);
		rebind = true;
	}
	const struct state_table_quality *tq = &s->quality.t[STATE_TRANSMITTANCE];
	VkDeviceSize column_bytes = (VkDeviceSize)tq->width * tq->height * 4 * sizeof(float);
	if (!e->columns.buf || e->columns.bytes != column_bytes) {
		vec4_buffer_free(e, &e->columns, &e->columns_view);
		e->columns_valid = false;
		rc = vec4_buffer_new(e, column_bytes, &e->columns, &e->columns_view, err, err_size);
		if (rc < 0)
			return rc;
		rebind = true;
	}
	const struct state_table_quality *mq = &s->quality.t[STATE_MULTISCATTER];
	VkDeviceSize iterate_bytes = e->table_bytes[STATE_MULTISCATTER] +
				     (VkDeviceSize)mq->width * mq->height * 4 * sizeof(float);
	if (!e->ms_iterate.buf || e->ms_iterate.bytes != iterate_bytes) {
		buffer_free(e, &e->ms_iterate);
		rc = buffer_new(e, iterate_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
						  VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
				VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, &e->ms_iterate, err, err_size);
		if (rc < 0)
			return rc;
		rebind = true;
	}
	VkDeviceSize moment_bytes = (VkDeviceSize)mq->width * mq->height * 4 * sizeof(float);
	if (!e->moment.buf || e->moment.bytes != moment_bytes) {
		vec4_buffer_free(e, &e->moment, &e->moment_view);
		/* Its contents go with the multi-scattering table's, which is
		 * recomputed whenever its size (and so this one's) changes. */
		rc = vec4_buffer_new(e, moment_bytes, &e->moment, &e->moment_view, err, err_size);
		if (rc < 0)
			return rc;
		rebind = true;
	}
	if (rebind) {
		VkDescriptorBufferInfo bi[N_BINDINGS] = { { e->params.buf, 0, VK_WHOLE_SIZE } };
		VkWriteDescriptorSet w[N_BINDINGS];
		for (int i = 0; i < N_BINDINGS; i++) {
			w[i] = (VkWriteDescriptorSet){ .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
				.dstSet = e->set, .dstBinding = (uint32_t)i, .descriptorCount = 1,
				.descriptorType = binding_type(i) };
			if (i > STATE_N_TABLES && i < VIEWS_BINDING) {
				w[i].pTexelBufferView = &e->lookup_view[i - 1 - STATE_N_TABLES];
				continue;
			}
			if (i == MOMENT_TEX_BINDING) {
				w[i].pTexelBufferView = &e->moment_view;
				continue;
			}
			if (i == COLUMNS_TEX_BINDING) {
				w[i].pTexelBufferView = &e->columns_view;
				continue;
			}
			if (i == VIEWS_BINDING)
				bi[i] = (VkDescriptorBufferInfo){ e->views.buf, 0, VK_WHOLE_SIZE };
			else if (i == COLUMNS_BINDING)
				bi[i] = (VkDescriptorBufferInfo){ e->columns.buf, 0, VK_WHOLE_SIZE };
			else if (i == ITERATE_BINDING)
				bi[i] = (VkDescriptorBufferInfo){ e->ms_iterate.buf, 0, VK_WHOLE_SIZE };
			else if (i == MOMENT_BINDING)
				bi[i] = (VkDescriptorBufferInfo){ e->moment.buf, 0, VK_WHOLE_SIZE };
			else if (i > 0)
				bi[i] = (VkDescriptorBufferInfo){ e->table[i - 1].buf, 0, VK_WHOLE_SIZE };
			w[i].pBufferInfo = &bi[i];
		}
		e->vk.vkUpdateDescriptorSets(e->dev, N_BINDINGS, w, 0, NULL);
	}
	*ret_lost = lost;
fail:
	return rc;
}

static void groups(const struct sky_state *s, int t, uint32_t *x, uint32_t *y)
{
	const struct state_table_quality *q = &s->quality.t[t];
	/* Multi-scattering and sky-view invocations compute several texels of a row. */
	uint32_t g = t == STATE_MULTISCATTER ? MS_SUN_GROUP : t == STATE_SKYVIEW ? SV_AZ_GROUP : 1;
	uint32_t w = (q->width + g - 1) / g;
	/* Workgroups are 8 x 8, but 4 x 16 for sky-view (skyview.comp). */
	uint32_t lx = 8, ly = 8;
	*x = (w + lx - 1) / lx;
	*y = (q->height + ly - 1) / ly;
}

/* Records one pass: its dispatch between two timestamps (queries 2 pass and
 * 2 pass + 1), then a barrier so that the next pass reads what it wrote. */
static void record_pass(struct eng *e, int pass, VkPipeline pipe, uint32_t gx, uint32_t gy,
			uint32_t gz)
{
	const VkMemoryBarrier compute_to_compute = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT, .dstAccessMask = VK_ACCESS_SHADER_READ_BIT };

	if (e->timestamps)
		e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, e->queries,
					  2 * (uint32_t)pass);
	e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipe);
	e->vk.vkCmdDispatch(e->cmd, gx, gy, gz);
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
				   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &compute_to_compute, 0,
				   NULL, 0, NULL);
	if (e->timestamps)
		e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, e->queries,
					  2 * (uint32_t)pass + 1);
}

/* Records the steps of the iteration of psi_ms after the multi-scattering
 * pass: each step writes the next table into the scratch buffer, which is
 * then copied over the table (later passes and the next step read it
 * through the lookup view). One pair of timestamps spans all steps. */
static void record_iteration(struct eng *e, const struct sky_state *s, const VkPipeline pipes[2],
			     uint32_t steps)
{
	const VkMemoryBarrier to_copy = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_SHADER_READ_BIT,
		.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT };
	const VkMemoryBarrier to_read = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
		.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT };
	uint32_t gx, gy;

	groups(s, STATE_MULTISCATTER, &gx, &gy);
	if (e->timestamps)
		e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, e->queries,
					  2 * PASS_MSITERATE);
	for (uint32_t i = 0; i < steps; i++) {
		e->vk.vkCmdBindPipeline(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipes[i > 0]);
		e->vk.vkCmdDispatch(e->cmd, gx, gy, 1);
		e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
					   VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &to_copy, 0, NULL, 0, NULL);
		VkBufferCopy c = { 0, 0, e->table_bytes[STATE_MULTISCATTER] };
		e->vk.vkCmdCopyBuffer(e->cmd, e->ms_iterate.buf, e->table[STATE_MULTISCATTER].buf, 1, &c);
		e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
					   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &to_read, 0, NULL, 0,
					   NULL);
	}
	if (e->timestamps)
		e->vk.vkCmdWriteTimestamp(e->cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, e->queries,
					  2 * PASS_MSITERATE + 1);
}

int eng_submit(struct eng *e, const struct sky_state *s, uint32_t mask, char *err, size_t err_size)
{
	struct gpu_params params;
	struct spec base;
	uint32_t lost = 0;
	int rc = 0;

	pthread_mutex_lock(&e->lock);
	bool busy = e->pending || e->finished;
	pthread_mutex_unlock(&e->lock);
	if (busy) {
		set_err(err, err_size, "a computation is in flight");
		return -EBUSY;
	}
	for (int t = 0; t < STATE_N_TABLES; t++) {
		const struct state_table_quality *q = &s->quality.t[t];
		uint32_t gx, gy;
		groups(s, t, &gx, &gy);
		if (t < N_LOOKUPS && (uint64_t)q->width * q->height > e->limits.maxTexelBufferElements) {
			set_err(err, err_size, "%s_width: %ux%u texels exceed the device's %u for a lookup table",
				state_table_names[t], q->width, q->height,
				e->limits.maxTexelBufferElements);
			return -EINVAL;
		}
		if (gx > e->limits.maxComputeWorkGroupCount[0] ||
		    gy > e->limits.maxComputeWorkGroupCount[1] || q->width == 0 || q->height == 0) {
			set_err(err, err_size, "%s_width: %ux%u is beyond the device's limits",
				state_table_names[t], q->width, q->height);
			return -EINVAL;
		}
	}
	rc = ensure_tables(e, s, &lost, err, err_size);
	if (rc < 0)
		return rc;
	/* Exactly mask: a table the caller did not ask for is neither computed
	 * nor forced, so demand decides the cost. Only a dependency of mask
	 * whose buffer was reallocated must come along. */
	mask |= lost & state_closure(mask);

	fill_params(e, s, &params, &base);
	VkPipeline pipes[STATE_N_TABLES] = { 0 }, column_pipe = VK_NULL_HANDLE;
	for (int t = 0; t < STATE_N_TABLES; t++)
		if (mask & STATE_BIT(t)) {
			struct spec k = pass_spec(&base, s, t);
			rc = get_pipeline(e, t, &k, &pipes[t], err, err_size);
			if (rc < 0)
				return rc;
		}
	/* The iteration of psi_ms: its first step recovers L2 from the table,
	 * the later ones read it back (constant_id 21). */
	uint32_t iterations = (mask & STATE_BIT(STATE_MULTISCATTER)) ? state_multiscatter_iterations(s) : 0;
	VkPipeline iterate_pipes[2] = { VK_NULL_HANDLE, VK_NULL_HANDLE };
	for (int i = 0; i < 2 && iterations > 0; i++) {
		struct spec k = pass_spec(&base, s, STATE_MULTISCATTER);
		k.v[21] = i == 0;
		rc = get_pipeline(e, PASS_MSITERATE, &k, &iterate_pipes[i], err, err_size);
		if (rc < 0)
			return rc;
	}
	/* The column densities are recomputed only when what they depend on
	 * changed; the same inputs give the same bits, so a table made from
	 * kept columns is the one a fresh engine makes. */
	struct spec ck = column_spec(&base, s);
	struct column_key key;
	column_key(&params, &ck, &key);
	bool run_columns = (mask & STATE_BIT(STATE_TRANSMITTANCE)) &&
			   (!e->columns_valid || memcmp(&key, &e->column_key, sizeof(key)));
	if (run_columns) {
		rc = get_pipeline(e, PASS_COLUMNS, &ck, &column_pipe, err, err_size);
		if (rc < 0)
			return rc;
	}
	memcpy(e->params.map, &params, sizeof(params));
	fill_views(s, e->views.map);

	VkCommandBufferBeginInfo bi = { .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
		.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT };
	VK_TRY(e->vk.vkBeginCommandBuffer(e->cmd, &bi));
	if (e->timestamps)
		e->vk.vkCmdResetQueryPool(e->cmd, e->queries, 0, 2 * N_PASSES);
	e->vk.vkCmdBindDescriptorSets(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, e->pipe_layout, 0, 1,
				      &e->set, 0, NULL);
	for (int t = 0; t < STATE_N_TABLES; t++) {
		if (!(mask & STATE_BIT(t)))
			continue;
		uint32_t gx, gy;
		groups(s, t, &gx, &gy);
		if (t == STATE_TRANSMITTANCE && run_columns)
			record_pass(e, PASS_COLUMNS, column_pipe, gx, gy, 1);
		/* Every view's volume in one dispatch: z is the view. */
		record_pass(e, t, pipes[t], gx, gy, t == STATE_AERIAL ? 1 + s->n_views : 1);
		if (t == STATE_MULTISCATTER && iterations > 0)
			record_iteration(e, s, iterate_pipes, iterations);
	}
	VkMemoryBarrier to_copy = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT, .dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT };
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
				   VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &to_copy, 0, NULL, 0, NULL);
	for (int t = 0; t < STATE_N_TABLES; t++)
		if (mask & STATE_BIT(t)) {
			VkBufferCopy c = { 0, 0, e->table_bytes[t] };
			e->vk.vkCmdCopyBuffer(e->cmd, e->table[t].buf, e->readback[t].buf, 1, &c);
		}
	VkMemoryBarrier to_host = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT, .dstAccessMask = VK_ACCESS_HOST_READ_BIT };
	e->vk.vkCmdPipelineBarrier(e->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT,
				   0, 1, &to_host, 0, NULL, 0, NULL);
	VK_TRY(e->vk.vkEndCommandBuffer(e->cmd));
	VK_TRY(e->vk.vkResetFences(e->dev, 1, &e->fence));
	VkSubmitInfo si = { .sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1,
		.pCommandBuffers = &e->cmd };
	clock_gettime(CLOCK_MONOTONIC, &e->submit_time);
	VK_TRY(e->vk.vkQueueSubmit(e->queue, 1, &si, e->fence));

	if (run_columns) {
		/* Invalidated again if the computation fails (eng_complete). */
		e->column_key = key;
		e->columns_valid = true;
	}
	e->columns_in_flight = run_columns;
	e->iterations_in_flight = iterations;
	pthread_mutex_lock(&e->lock);
	e->in_flight_mask = mask;
	e->pending = true;
	e->finished = false;
	pthread_cond_signal(&e->cond);
	pthread_mutex_unlock(&e->lock);
	return 0;
fail:
	return rc;
}

int eng_complete(struct eng *e, struct eng_timing *ret, char *err, size_t err_size)
{
	struct timespec now;
	uint64_t count;
	int rc = 0;

	pthread_mutex_lock(&e->lock);
	bool done = e->finished;
	VkResult wr = e->wait_result;
	uint32_t mask = e->in_flight_mask;
	pthread_mutex_unlock(&e->lock);
	if (!done)
		return -EAGAIN;
	clock_gettime(CLOCK_MONOTONIC, &now);
	while (read(e->event_fd, &count, sizeof(count)) == sizeof(count))
		;

	struct eng_timing t = { .computed = mask, .total_ms = elapsed_ms(&e->submit_time, &now),
		.columns = e->columns_in_flight };
	pthread_mutex_lock(&e->lock);
	e->finished = false;
	pthread_mutex_unlock(&e->lock);
	if (wr != VK_SUCCESS)
		e->columns_valid = false;
	VK_TRY(wr);
	for (int i = 0; i < STATE_N_TABLES; i++) {
		if (!(mask & STATE_BIT(i)))
			continue;
		VkMappedMemoryRange r = { .sType = VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE,
			.memory = e->readback[i].mem, .size = VK_WHOLE_SIZE };
		VK_TRY(e->vk.vkInvalidateMappedMemoryRanges(e->dev, 1, &r));
	}
	if (e->timestamps) {
		uint64_t ts[2 * STATE_N_TABLES];
		for (int i = 0; i < STATE_N_TABLES; i++) {
			if (!(mask & STATE_BIT(i)))
				continue;
			VK_TRY(e->vk.vkGetQueryPoolResults(e->dev, e->queries, 2 * i, 2, sizeof(uint64_t) * 2,
							   &ts[2 * i], sizeof(uint64_t),
							   VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
			t.table_ms[i] = (double)(ts[2 * i + 1] - ts[2 * i]) * e->timestamp_period_ns * 1e-6;
		}
		if (t.columns) {
			VK_TRY(e->vk.vkGetQueryPoolResults(e->dev, e->queries, 2 * PASS_COLUMNS, 2,
							   sizeof(uint64_t) * 2, ts, sizeof(uint64_t),
							   VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
			t.columns_ms = (double)(ts[1] - ts[0]) * e->timestamp_period_ns * 1e-6;
			t.table_ms[STATE_TRANSMITTANCE] += t.columns_ms;
		}
		if (e->iterations_in_flight) {
			VK_TRY(e->vk.vkGetQueryPoolResults(e->dev, e->queries, 2 * PASS_MSITERATE, 2,
							   sizeof(uint64_t) * 2, ts, sizeof(uint64_t),
							   VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
			t.table_ms[STATE_MULTISCATTER] += (double)(ts[1] - ts[0]) * e->timestamp_period_ns * 1e-6;
		}
	}
	*ret = t;
	return 0;
fail:
	return rc;
}

int eng_wait(struct eng *e, struct eng_timing *ret, char *err, size_t err_size)
{
	struct pollfd p = { .fd = e->event_fd, .events = POLLIN };
	for (;;) {
		int rc = eng_complete(e, ret, err, err_size);
		if (rc != -EAGAIN)
			return rc;
		pthread_mutex_lock(&e->lock);
		bool idle = !e->pending && !e->finished;
		pthread_mutex_unlock(&e->lock);
		if (idle) {
			set_err(err, err_size, "nothing was submitted");
			return -EINVAL;
		}
		if (poll(&p, 1, -1) < 0 && errno != EINTR)
			return -errno;
	}
}

int eng_compute(struct eng *e, const struct sky_state *s, uint32_t mask, struct eng_timing *ret,
		char *err, size_t err_size)
{
	int rc = eng_submit(e, s, mask, err, err_size);
	return rc < 0 ? rc : eng_wait(e, ret, err, err_size);
}
