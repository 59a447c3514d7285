/* eng_run.c - running a computation: its plan (eng_pass.c) recorded into
 * the one command buffer with the copies of its published tables
 * (eng_host.c), one submission, and completion through the waiter thread's
 * eventfd. A plan that lacks pipelines waits for the waiter thread to make
 * them first. */
#include "eng_internal.h"

#include <errno.h>
#include <poll.h>
#include <stddef.h>
#include <string.h>
#include <unistd.h>

static double elapsed_ms(const struct timespec *a, const struct timespec *b)
{
	return (b->tv_sec - a->tv_sec) * 1e3 + (b->tv_nsec - a->tv_nsec) * 1e-6;
}

/* Records pl into e->cmd: the passes, then the copies of the published
 * tables where target says. */
static int record(struct eng *e, const struct sky_state *s, const struct plan *pl,
		  const struct eng_target *target, char *err, size_t err_size)
{
	int rc = 0;
	VkCommandBufferBeginInfo bi = { .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
		.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT };
	VK_TRY(e->vk.vkBeginCommandBuffer(e->cmd, &bi));
	if (e->timestamps)
		e->vk.vkCmdResetQueryPool(e->cmd, e->queries, 0, 2 * N_PASSES);
	e->vk.vkCmdBindDescriptorSets(e->cmd, VK_PIPELINE_BIND_POINT_COMPUTE, e->pipe_layout, 0, 1,
				      &e->set, 0, NULL);
	eng_record_image_layouts(e);
	eng_record_passes(e, s, pl);
	eng_record_publish(e, s, target, pl->mask);
	VK_TRY(e->vk.vkEndCommandBuffer(e->cmd));
fail:
	return rc;
}

/* Hands the plan's orders to the waiter thread; eng_complete submits the
 * call again once they are made. The caller's inputs are copied: they may
 * change before then. */
static void defer(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		  uint32_t mask, const struct eng_target *target)
{
	e->deferred.s = *s;
	e->deferred.lights = *lights;
	e->deferred.mask = mask;
	e->deferred.orders = e->n_orders;
	e->deferred.has_target = target != NULL;
	if (target)
		e->deferred.target = *target;
	pthread_mutex_lock(&e->lock);
	e->compiling = true;
	e->in_flight_mask = mask;
	e->pending = true;
	e->finished = false;
	pthread_cond_signal(&e->cond);
	pthread_mutex_unlock(&e->lock);
}

int eng_submit(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
	       uint32_t mask, char *err, size_t err_size)
{
	return eng_submit_to(e, s, lights, mask, NULL, err, err_size);
}

int eng_submit_to(struct eng *e, const struct sky_state *s, const struct state_lights *lights,
		  uint32_t mask, const struct eng_target *target, char *err, size_t err_size)
{
	struct gpu_params params;
	struct state_lights own;
	struct plan *pl = &e->flight;
	uint32_t lost = 0;
	int rc = 0;

	pthread_mutex_lock(&e->lock);
	bool busy = e->pending || e->finished;
	pthread_mutex_unlock(&e->lock);
	if (busy) {
		eng_set_err(err, err_size, "a computation is in flight");
		return -EBUSY;
	}
	if (!lights) {
		state_lights_of(s, &own);
		lights = &own;
	}
	/* The plan of this computation: the buffers' sizes and the jobs (a
	 * computation made ahead computes no aerial perspective and keeps
	 * the last one's), and the cloud tables made ahead for s bound. */
	if (!e->ahead_flight) {
		aplan_make_lit(s, lights, e->share_views, &e->aplan);
		if (!e->resubmitting)
			e->took_ahead = false;
		if (eng_take_ahead(e, s, lights))
			e->took_ahead = true;
	}
	rc = eng_check_limits(e, s, err, err_size);
	if (rc == 0)
		rc = eng_ensure_tables(e, s, &lost, err, err_size);
	if (rc < 0)
		return rc;
	/* Exactly mask: a table the caller did not ask for is neither computed
	 * nor forced, so demand decides the cost. Only a dependency of mask
	 * whose buffer was reallocated must come along. */
	mask |= lost & state_closure(mask);
	rc = eng_make_plan(e, s, lights, mask, &params, pl, err, err_size);
	if (rc < 0)
		return rc;
	if (e->n_orders > 0) {
		defer(e, s, lights, mask, target);
		return 0;
	}
	mask = pl->mask;	/* with the cloud tables its reads need */
	if (s->quality.storage == STATE_F16) {
		struct gpu_pack pack;
		memset(&pack, 0, sizeof(pack));
		for (int t = STATE_MULTISCATTER; t < STATE_N_TABLES; t++)
			pack.texels[t] = (mask & STATE_BIT(t)) ? (uint32_t)eng_table_texels(e, s, t) : 0;
		memcpy(e->pack.map, &pack, sizeof(pack));
	}
	rc = record(e, s, pl, target, err, err_size);
	if (rc < 0)
		return rc;
	VK_TRY(e->vk.vkResetFences(e->dev, 1, &e->fence));
	VkSubmitInfo si = { .sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1,
		.pCommandBuffers = &e->cmd };
	clock_gettime(CLOCK_MONOTONIC, &e->submit_time);
	VK_TRY(e->vk.vkQueueSubmit(e->queue, 1, &si, e->fence));

	if (pl->run[PASS_COLUMNS].on) {
		/* Invalidated again if the computation fails (eng_complete). */
		e->column_key = pl->key;
		e->columns_valid = true;
	}
	if (pl->run[PASS_SHADOW].on) {
		/* Invalidated again if the computation fails (eng_complete). */
		e->ct.key = pl->clouds;
		e->ct.valid = true;
		e->ct.moon_zero = pl->run[PASS_SHADOW].groups[2] < 2;
	}
	if (pl->run[PASS_SKYVIEW].on && pl->sv_keyed) {
		e->sv_last = pl->sv_key;
		e->sv_last_valid = true;
	}
	if (pl->run[PASS_SKYVIEW].on && pl->run[PASS_SKYVIEW].key.v[SPEC_SV_KEPT] == SV_KEPT_WRITE) {
		/* Invalidated again if the computation fails (eng_complete). */
		e->sv_light_key = pl->sv_key;
		e->sv_light_valid = true;
	}
	if (pl->run[PASS_LOOKUP_IMAGES].on)
		e->images_valid = true;
	else if (mask & ENG_LOOKUP_TABLES)
		e->images_valid = false;
	e->pack_in_flight = s->quality.storage == STATE_F16;
	pthread_mutex_lock(&e->lock);
	e->has_target = target && target->base;
	if (e->has_target)
		e->target = *target;
	e->in_flight_mask = mask;
	e->pending = true;
	e->finished = false;
	pthread_cond_signal(&e->cond);
	pthread_mutex_unlock(&e->lock);
	return 0;
fail:
	return rc;
}

/* Makes what the computation wrote visible to the host: the host copies
 * of mask and, where the device writes imported memory, nothing (host
 * allocations are coherent). */
static int invalidate(struct eng *e, uint32_t mask, char *err, size_t err_size)
{
	int rc = 0;
	for (int i = 0; i < STATE_N_TABLES; i++) {
		if (!(mask & STATE_BIT(i)) || !e->host_fresh[i])
			continue;
		VkMappedMemoryRange r = { .sType = VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE,
			.memory = e->direct[i] ? e->table[i].mem : e->readback[i].mem, .size = VK_WHOLE_SIZE };
		VK_TRY(e->vk.vkInvalidateMappedMemoryRanges(e->dev, 1, &r));
	}
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
	if (e->compiling) {
		pthread_mutex_lock(&e->lock);
		e->compiling = e->finished = false;
		pthread_mutex_unlock(&e->lock);
		if (wr != VK_SUCCESS) {
			eng_end_ahead(e);
			vkcheck_describe(err, err_size, "vkCreateComputePipelines", wr, __FILE_NAME__,
					 __LINE__);
			return wr == VK_ERROR_OUT_OF_HOST_MEMORY ? -ENOMEM : -EIO;
		}
		e->resubmitting = true;
		rc = eng_submit_to(e, &e->deferred.s, &e->deferred.lights, e->deferred.mask,
				   e->deferred.has_target ? &e->deferred.target : NULL, err, err_size);
		e->resubmitting = false;
		if (rc < 0)
			eng_end_ahead(e);
		return rc < 0 ? rc : -EAGAIN;
	}

	struct eng_timing t = { .computed = mask, .total_ms = elapsed_ms(&e->submit_time, &now),
		.columns = e->flight.run[PASS_COLUMNS].on,
		.skyview_light_kept = e->flight.run[PASS_SKYVIEW].on &&
				      e->flight.run[PASS_SKYVIEW].key.v[SPEC_SV_KEPT] == SV_KEPT_READ,
		.clouds_ahead = e->took_ahead && !e->ahead_flight };
	e->took_ahead = false;
	pthread_mutex_lock(&e->lock);
	e->finished = false;
	e->has_target = false;
	pthread_mutex_unlock(&e->lock);
	if (wr != VK_SUCCESS)
		e->columns_valid = e->images_valid = e->ct.valid = e->ct.moon_zero = e->sv_light_valid = false;
	eng_end_ahead(e);
	VK_TRY(wr);
	rc = invalidate(e, mask, err, err_size);
	if (rc < 0)
		return rc;
	for (int i = 0; i < STATE_N_TABLES; i++)
		if (mask & STATE_BIT(i))
			e->rgb_scale_log2[i] = !e->pack_in_flight ? 0
					       : i == STATE_TRANSMITTANCE ? SKY_F16_TRANSMITTANCE_LOG2
					       : ((const struct gpu_pack *)e->pack.map)->scale_log2[i];
	rc = eng_pass_times(e, &e->flight, &t, err, err_size);
	if (rc < 0)
		return rc;
	if (e->pipelines_created > e->pipelines_saved)
		eng_save_cache(e);
	*ret = t;
	return 0;
fail:
	return rc;
}

void eng_wait_orders(const struct eng *e)
{
	struct pollfd p = { .fd = e->event_fd, .events = POLLIN };
	while (e->compiling && poll(&p, 1, -1) < 0 && errno == EINTR)
		;
}

void eng_set_view_sharing(struct eng *e, int share)
{
	e->share_views = share != 0;
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
			eng_set_err(err, err_size, "nothing was submitted");
			return -EINVAL;
		}
		if (poll(&p, 1, -1) < 0 && errno != EINTR)
			return -errno;
	}
}

int eng_compute(struct eng *e, const struct sky_state *s, uint32_t mask, struct eng_timing *ret,
		char *err, size_t err_size)
{
	int rc = eng_submit(e, s, NULL, mask, err, err_size);
	return rc < 0 ? rc : eng_wait(e, ret, err, err_size);
}
