/* frame.c - skyrender's render pass, its two pipelines (the terrain mesh
 * with depth, then the sky on every pixel the terrain left), the
 * descriptor sets of the table images, and the recording of one frame with
 * its copy to the read-back buffer. */
#include <errno.h>
#include <stddef.h>
#include <string.h>

#include "rvk_internal.h"
#include "terrain.h"

#include "sky.vert.spv.h"
#include "sky.frag.spv.h"
#include "terrain.vert.spv.h"
#include "terrain.frag.spv.h"

#define TERRAIN_GRID 257		/* vertices per side */
#define TERRAIN_RADIUS_KM 90.0
#define TERRAIN_SEED 7u

static int shader_module(struct rvk *r, const uint32_t *code, size_t bytes, VkShaderModule *ret,
			 char *err, size_t err_size)
{
	VkShaderModuleCreateInfo ci = { .sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO,
		.codeSize = bytes, .pCode = code };
	int rc = 0;
	VK_TRY(vkCreateShaderModule(r->dev, &ci, NULL, ret));
	return 0;
fail:
	return rc;
}

static int pass_init(struct rvk *r, char *err, size_t err_size)
{
	VkAttachmentDescription at[2] = {
		{ .format = r->colour.format, .samples = VK_SAMPLE_COUNT_1_BIT,
		  .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR, .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
		  .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
		  .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
		  .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED,
		  .finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL },
		{ .format = r->depth.format, .samples = VK_SAMPLE_COUNT_1_BIT,
		  .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR, .storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
		  .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
		  .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
		  .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED,
		  .finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL },
	};
	VkAttachmentReference cref = { 0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL };
	VkAttachmentReference dref = { 1, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL };
	VkSubpassDescription sub = { .pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
		.colorAttachmentCount = 1, .pColorAttachments = &cref,
		.pDepthStencilAttachment = &dref };
	VkSubpassDependency dep = { .srcSubpass = 0, .dstSubpass = VK_SUBPASS_EXTERNAL,
		.srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
		.dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT,
		.srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
		.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT };
	VkRenderPassCreateInfo pi = { .sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO,
		.attachmentCount = 2, .pAttachments = at, .subpassCount = 1, .pSubpasses = &sub,
		.dependencyCount = 1, .pDependencies = &dep };
	int rc = 0;
	VK_TRY(vkCreateRenderPass(r->dev, &pi, NULL, &r->pass));
	VkImageView views[2] = { r->colour.view, r->depth.view };
	VkFramebufferCreateInfo fi = { .sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
		.renderPass = r->pass, .attachmentCount = 2, .pAttachments = views,
		.width = r->colour.width, .height = r->colour.height, .layers = 1 };
	VK_TRY(vkCreateFramebuffer(r->dev, &fi, NULL, &r->fb));
	return 0;
fail:
	return rc;
}

static int layout_init(struct rvk *r, char *err, size_t err_size)
{
	/* 0: the uniform block; 1 to 5: transmittance, sky-view,
	 * multi-scattering, the clouds' coverage and the sun's shadow map
	 * (enum rvk_table); 6: the aerial textures (volumes or a panorama),
	 * an array. */
	VkDescriptorSetLayoutBinding b[1 + RVK_AERIAL + 1];
	int rc = 0;
	for (uint32_t i = 0; i < 1 + RVK_AERIAL + 1; i++)
		b[i] = (VkDescriptorSetLayoutBinding){ .binding = i,
			.descriptorCount = i == 1 + RVK_AERIAL ? RVK_MAX_AERIAL : 1,
			.descriptorType = i == 0 ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER :
						   VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
			.stageFlags = VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT };
	VkDescriptorSetLayoutCreateInfo li = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
		.bindingCount = 1 + RVK_AERIAL + 1, .pBindings = b };
	VK_TRY(vkCreateDescriptorSetLayout(r->dev, &li, NULL, &r->set_layout));
	VkPipelineLayoutCreateInfo pli = { .sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
		.setLayoutCount = 1, .pSetLayouts = &r->set_layout };
	VK_TRY(vkCreatePipelineLayout(r->dev, &pli, NULL, &r->pipe_layout));
	VkDescriptorPoolSize ps[2] = { { VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 2 },
				       { VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 2 * RVK_TABLES } };
	VkDescriptorPoolCreateInfo pi = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
		.maxSets = 2, .poolSizeCount = 2, .pPoolSizes = ps };
	VK_TRY(vkCreateDescriptorPool(r->dev, &pi, NULL, &r->desc_pool));
	VkDescriptorSetLayout layouts[2] = { r->set_layout, r->set_layout };
	VkDescriptorSet sets[2];
	VkDescriptorSetAllocateInfo ai = { .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
		.descriptorPool = r->desc_pool, .descriptorSetCount = 2, .pSetLayouts = layouts };
	VK_TRY(vkAllocateDescriptorSets(r->dev, &ai, sets));
	r->sets[0].desc = sets[0];
	r->sets[1].desc = sets[1];
	return 0;
fail:
	return rc;
}

/* One pipeline: terrain (vertices, depth test and write) or sky (a
 * full-screen triangle where the depth is still the cleared far value). */
static int pipeline_new(struct rvk *r, bool terrain, VkPipeline *ret, char *err, size_t err_size)
{
	VkShaderModule vs = VK_NULL_HANDLE, fs = VK_NULL_HANDLE;
	int rc = terrain ?
		shader_module(r, terrain_vert_spv, sizeof(terrain_vert_spv), &vs, err, err_size) :
		shader_module(r, sky_vert_spv, sizeof(sky_vert_spv), &vs, err, err_size);
	if (rc == 0)
		rc = terrain ?
			shader_module(r, terrain_frag_spv, sizeof(terrain_frag_spv), &fs, err, err_size) :
			shader_module(r, sky_frag_spv, sizeof(sky_frag_spv), &fs, err, err_size);
	if (rc < 0)
		goto fail;
	VkPipelineShaderStageCreateInfo st[2] = {
		{ .sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
		  .stage = VK_SHADER_STAGE_VERTEX_BIT, .module = vs, .pName = "main" },
		{ .sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
		  .stage = VK_SHADER_STAGE_FRAGMENT_BIT, .module = fs, .pName = "main" },
	};
	VkVertexInputBindingDescription vb = { 0, sizeof(struct terrain_vertex),
					       VK_VERTEX_INPUT_RATE_VERTEX };
	VkVertexInputAttributeDescription va[2] = {
		{ 0, 0, VK_FORMAT_R32G32B32_SFLOAT, offsetof(struct terrain_vertex, position_km) },
		{ 1, 0, VK_FORMAT_R32G32B32_SFLOAT, offsetof(struct terrain_vertex, normal) },
	};
	VkPipelineVertexInputStateCreateInfo vi = {
		.sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO,
		.vertexBindingDescriptionCount = terrain ? 1 : 0, .pVertexBindingDescriptions = &vb,
		.vertexAttributeDescriptionCount = terrain ? 2 : 0, .pVertexAttributeDescriptions = va };
	VkPipelineInputAssemblyStateCreateInfo ia = {
		.sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO,
		.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST };
	VkViewport vp = { 0, 0, (float)r->colour.width, (float)r->colour.height, 0, 1 };
	VkRect2D sc = { { 0, 0 }, { r->colour.width, r->colour.height } };
	VkPipelineViewportStateCreateInfo vps = {
		.sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO,
		.viewportCount = 1, .pViewports = &vp, .scissorCount = 1, .pScissors = &sc };
	VkPipelineRasterizationStateCreateInfo rs = {
		.sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO,
		.polygonMode = VK_POLYGON_MODE_FILL, .cullMode = VK_CULL_MODE_NONE,
		.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE, .lineWidth = 1.0f };
	VkPipelineMultisampleStateCreateInfo ms = {
		.sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO,
		.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT };
	/* Reversed depth: cleared to 0 (infinitely far), nearer is greater. */
	VkPipelineDepthStencilStateCreateInfo ds = {
		.sType = VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO,
		.depthTestEnable = VK_TRUE, .depthWriteEnable = terrain ? VK_TRUE : VK_FALSE,
		.depthCompareOp = terrain ? VK_COMPARE_OP_GREATER : VK_COMPARE_OP_EQUAL };
	VkPipelineColorBlendAttachmentState cba = { .colorWriteMask = 0xf };
	VkPipelineColorBlendStateCreateInfo cb = {
		.sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO,
		.attachmentCount = 1, .pAttachments = &cba };
	VkGraphicsPipelineCreateInfo gi = { .sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO,
		.stageCount = 2, .pStages = st, .pVertexInputState = &vi, .pInputAssemblyState = &ia,
		.pViewportState = &vps, .pRasterizationState = &rs, .pMultisampleState = &ms,
		.pDepthStencilState = &ds, .pColorBlendState = &cb, .layout = r->pipe_layout,
		.renderPass = r->pass };
	VK_TRY(vkCreateGraphicsPipelines(r->dev, VK_NULL_HANDLE, 1, &gi, NULL, ret));
fail:
	if (vs)
		vkDestroyShaderModule(r->dev, vs, NULL);
	if (fs)
		vkDestroyShaderModule(r->dev, fs, NULL);
	return rc;
}

/* The terrain mesh, in host-visible buffers (written once). */
static int terrain_init(struct rvk *r, char *err, size_t err_size)
{
	struct terrain_mesh m;
	/* The mesh is built for the Earth's radius; its curvature is a few
	 * hundred metres at the edge, so another planet shows it only there. */
	int rc = terrain_mesh_init(TERRAIN_GRID, TERRAIN_RADIUS_KM, 6360.0, TERRAIN_SEED, &m);
	if (rc < 0) {
		rvk_set_err(err, err_size, "terrain: out of memory");
		return rc;
	}
	size_t vb = (size_t)m.vertex_count * sizeof(*m.vertices), ib = (size_t)m.index_count * 4;
	rc = rvk_buffer_new(r, vb, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, true, &r->terrain_vertices,
			    err, err_size);
	if (rc == 0)
		rc = rvk_buffer_new(r, ib, VK_BUFFER_USAGE_INDEX_BUFFER_BIT, true,
				    &r->terrain_indices, err, err_size);
	if (rc == 0) {
		memcpy(r->terrain_vertices.map, m.vertices, vb);
		memcpy(r->terrain_indices.map, m.indices, ib);
		r->terrain_index_count = m.index_count;
	}
	terrain_mesh_finish(&m);
	return rc;
}

int rvk_frame_init(struct rvk *r, char *err, size_t err_size)
{
	int rc = pass_init(r, err, err_size);
	if (rc == 0)
		rc = layout_init(r, err, err_size);
	if (rc == 0)
		rc = pipeline_new(r, false, &r->sky_pipe, err, err_size);
	if (rc == 0 && r->opt.terrain)
		rc = pipeline_new(r, true, &r->terrain_pipe, err, err_size);
	if (rc == 0 && r->opt.terrain)
		rc = terrain_init(r, err, err_size);
	return rc;
}

void rvk_frame_finish(struct rvk *r)
{
	rvk_buffer_free(r, &r->terrain_vertices);
	rvk_buffer_free(r, &r->terrain_indices);
	if (r->sky_pipe)
		vkDestroyPipeline(r->dev, r->sky_pipe, NULL);
	if (r->terrain_pipe)
		vkDestroyPipeline(r->dev, r->terrain_pipe, NULL);
	if (r->pipe_layout)
		vkDestroyPipelineLayout(r->dev, r->pipe_layout, NULL);
	if (r->desc_pool)
		vkDestroyDescriptorPool(r->dev, r->desc_pool, NULL);
	if (r->set_layout)
		vkDestroyDescriptorSetLayout(r->dev, r->set_layout, NULL);
	if (r->fb)
		vkDestroyFramebuffer(r->dev, r->fb, NULL);
	if (r->pass)
		vkDestroyRenderPass(r->dev, r->pass, NULL);
}

int rvk_frame_bind_set(struct rvk *r, struct rvk_set *s, char *err, size_t err_size)
{
	VkDescriptorBufferInfo bi = { s->ubo.buf, 0, sizeof(struct rvk_frame_ubo) };
	VkDescriptorImageInfo ii[RVK_TABLES];
	VkWriteDescriptorSet w[1 + RVK_AERIAL + 1];
	w[0] = (VkWriteDescriptorSet){ .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
		.dstSet = s->desc, .dstBinding = 0, .descriptorCount = 1,
		.descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, .pBufferInfo = &bi };
	for (uint32_t i = 0; i < RVK_TABLES; i++)
		ii[i] = (VkDescriptorImageInfo){
			i == RVK_SKYVIEW ? r->sampler_wrap_u : r->sampler_clamp, s->tables[i].view,
			VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL };
	for (uint32_t i = 0; i <= RVK_AERIAL; i++)
		w[1 + i] = (VkWriteDescriptorSet){ .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
			.dstSet = s->desc, .dstBinding = 1 + i,
			.descriptorCount = i == RVK_AERIAL ? RVK_MAX_AERIAL : 1,
			.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
			.pImageInfo = &ii[i] };
	(void)err;
	(void)err_size;
	vkUpdateDescriptorSets(r->dev, 1 + RVK_AERIAL + 1, w, 0, NULL);
	return 0;
}

int rvk_frame_record(struct rvk *r, const struct rvk_set *s, char *err, size_t err_size)
{
	VkCommandBuffer cmd = r->draw_cmd;
	VkCommandBufferBeginInfo bi = { .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
		.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT };
	VkClearValue clear[2] = { { .color = { { 0, 0, 0, 1 } } }, { .depthStencil = { 0.0f, 0 } } };
	VkRenderPassBeginInfo rp = { .sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
		.renderPass = r->pass, .framebuffer = r->fb,
		.renderArea = { { 0, 0 }, { r->colour.width, r->colour.height } },
		.clearValueCount = 2, .pClearValues = clear };
	int rc = 0;

	VK_TRY(vkResetCommandBuffer(cmd, 0));
	VK_TRY(vkBeginCommandBuffer(cmd, &bi));
	vkCmdBeginRenderPass(cmd, &rp, VK_SUBPASS_CONTENTS_INLINE);
	vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipe_layout, 0, 1, &s->desc,
				0, NULL);
	if (r->terrain_pipe) {
		VkDeviceSize zero = 0;
		vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->terrain_pipe);
		vkCmdBindVertexBuffers(cmd, 0, 1, &r->terrain_vertices.buf, &zero);
		vkCmdBindIndexBuffer(cmd, r->terrain_indices.buf, 0, VK_INDEX_TYPE_UINT32);
		vkCmdDrawIndexed(cmd, r->terrain_index_count, 1, 0, 0, 0);
	}
	vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->sky_pipe);
	vkCmdDraw(cmd, 3, 1, 0, 0);
	vkCmdEndRenderPass(cmd);
	VkBufferImageCopy copy = { .imageSubresource = { VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1 },
		.imageExtent = { r->colour.width, r->colour.height, 1 } };
	vkCmdCopyImageToBuffer(cmd, r->colour.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
			       r->readback.buf, 1, &copy);
	VkMemoryBarrier mb = { .sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
		.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT, .dstAccessMask = VK_ACCESS_HOST_READ_BIT };
	vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
			     &mb, 0, NULL, 0, NULL);
	VK_TRY(vkEndCommandBuffer(cmd));
	return 0;
fail:
	return rc;
}
