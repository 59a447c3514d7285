// clouds.glsl - what the cloud passes and the sky marches share: the
// layers' block, the coverage table and the shadow maps as lookups, the
// light the cloud lets through toward a light at a point, the sky's light
// through the layers and the layers' own light in the air (docs/clouds.md,
// "In the tables"). Included after
// common.glsl; the maps are read only where SHADOW_W > 0 (a layer or the
// terrain casts), the layers only where CLOUD_LAYERS > 0.

#include "skycloud.glsl"

// struct ShadowFrame and the named lanes: sky_params.h.
layout(std430, binding = BINDING_CLOUDS) readonly buffer CloudBlock {
	SkycloudLayer layer[SKYCLOUD_MAX_LAYERS];
	vec4 field;
	vec4 terrain;
	uvec4 terrain_size;
	ShadowFrame frame[2];
	vec4 shift;	// xy: the field's move since the maps were made, km
} CL;
layout(binding = BINDING_CLOUD_TEX) uniform samplerBuffer CloudTex;
layout(binding = BINDING_SHADOW_TEX) uniform samplerBuffer ShadowTex;

layout(constant_id = SPEC_SHADOW_W) const int SHADOW_W = 1;	// a shadow map's width
layout(constant_id = SPEC_CLOUD_W) const int CLOUD_W = 1;	// the coverage table's
layout(constant_id = SPEC_CLOUD_PHASES) const int CLOUD_PHASES = CLOUD_PHASES_ONE;

// Private copies, made once per invocation by load_clouds() (as
// load_params(): lavapipe reloads a buffer read inside a loop at every
// use): the lights' frames, and per layer (top km, 1 / thickness, the
// vertical optical depth at full cover, cover) for cloud_sky_open.
ShadowFrame cloud_frame[2];
vec4 cloud_column[SKYCLOUD_MAX_LAYERS];
// Per layer, per unit of its vertical optical depth: the two-stream's
// 3/4 (1 - g) and the delta-scaled 1 - g^2 (cloud_reflectance).
vec2 cloud_slab[SKYCLOUD_MAX_LAYERS];
// The share of a map's optical depth that takes light off the light's
// direction: delta-Eddington's 1 - f with f = g^2 (conservative, omega 1),
// the layers' one phase (CLOUD_PHASES_ONE). With ice and water layers,
// the map keeps each texel's ice depth too (shadow_texel_tau): the
// scales of the phase above (met first from the light) and below.
float cloud_beam_scale = 1.0;
float cloud_scale_over = 1.0, cloud_scale_under = 1.0;
// The altitude of the march's step (cloud_at), km.
float cloud_h_km = 0.0;
// Above this altitude (km), at a point whose ray toward a light goes up,
// cloud_light is 1 exactly: no caster stands between the point and the
// light, and the bilinear read's other texels are clear there too. It is
// the casters' top plus one and a half of the lit maps' largest texel: a
// neighbouring texel's ray is at most that much lower at the same depth,
// so its cloud and terrain begin deeper than the point.
float cloud_ceiling_km = 0.0;

// enum skycloud_type's cirrus: ice, Henyey-Greenstein g 0.75; the water
// clouds' 0.85 (skycloud_types in proto/skycloud.h).
const int CLOUD_TYPE_CIRRUS = 5;

void load_clouds()
{
	if (SHADOW_W == 0)
		return;
	// The maps hold the field where the tables placed it; it has moved
	// on by shift since: a point reads the map where it was then.
	vec3 shift = vec3(CL.shift.xy, 0.0);
	for (int k = 0; k < 2; k++) {
		cloud_frame[k] = CL.frame[k];
		cloud_frame[k].u.w += dot(cloud_frame[k].u.xyz, shift);
		cloud_frame[k].v.w += dot(cloud_frame[k].v.xyz, shift);
		cloud_frame[k].l.w += dot(cloud_frame[k].l.xyz, shift);
	}
	for (int i = 0; i < CLOUD_LAYERS; i++)
		cloud_column[i] = vec4(CL.layer[i].top_km, CL.layer[i].inv_thickness_per_km,
				       CL.layer[i].extinction_per_km * (CL.layer[i].top_km - CL.layer[i].base_km) *
					       CL.layer[i].profile_integral,
				       CL.layer[i].cover);
	for (int i = 0; i < CLOUD_LAYERS; i++) {
		float g = CL.layer[i].type == CLOUD_TYPE_CIRRUS ? 0.75 : 0.85;
		cloud_slab[i] = vec2(0.75 * (1.0 - g), 1.0 - g * g);
	}
	cloud_beam_scale = CLOUD_LAYERS > 0 ? 0.0 : 1.0;
	for (int i = 0; i < CLOUD_LAYERS; i++)
		cloud_beam_scale = max(cloud_beam_scale, cloud_slab[i].y);
	for (int i = 0; CLOUD_PHASES != CLOUD_PHASES_ONE && i < CLOUD_LAYERS; i++) {
		bool over = (CL.layer[i].type == CLOUD_TYPE_CIRRUS) == (CLOUD_PHASES == CLOUD_PHASES_ICE_OVER);
		if (over)
			cloud_scale_over = cloud_slab[i].y;
		else
			cloud_scale_under = cloud_slab[i].y;
	}
	float top = CL.TERRAIN_TOP_KM, texel = 0.0;
	for (int i = 0; i < CLOUD_LAYERS; i++)
		top = max(top, cloud_column[i].x);
	for (int k = 0; k < (MOON_LIT ? 2 : 1); k++)
		texel = max(texel, max(1.0 / cloud_frame[k].U_TEXELS_PER_KM, 1.0 / cloud_frame[k].V_TEXELS_PER_KM));
	cloud_ceiling_km = top + 1.5 * texel;
}

// The optical depth of one map texel's column at depth d (km from the
// map's plane): Beer's law in the cloud span, front depth, mean
// extinction, capped at the column's whole (docs/clouds.md), delta-scaled
// (cloud_beam_scale): the droplets' forward peak, a share g^2 of what they
// scatter, goes on along the light, so the beam is what the peak leaves in
// it (docs/clouds.md, "In the tables"); beyond the terrain's opaque depth
// the light is gone.
//
// With ice and water layers (CLOUD_PHASES), ice is the texel's ice depth:
// the light meets the upper phase's whole depth (the ice's, or the rest)
// before the lower's, so up to depth d the column holds min(that, tau) of
// the upper and the rest of the lower, each scaled by its own 1 - g^2.
float shadow_texel_tau(vec4 s, float ice, float d)
{
	float tau = min(s.z, s.y * max(d - s.x, 0.0));
	if (CLOUD_PHASES == CLOUD_PHASES_ONE) {
		// The scale first: written tau * scale, lavapipe's code rounds
		// the tables of one phase differently in their last bits.
		tau = cloud_beam_scale * tau;
	} else {
		float upper = min(CLOUD_PHASES == CLOUD_PHASES_ICE_OVER ? ice : max(s.z - ice, 0.0), tau);
		tau = cloud_scale_over * upper + cloud_scale_under * (tau - upper);
	}
	return d > s.w ? 80.0 : tau;
}

// The transmittance of map texel i at depth d; the ice depths follow the
// two maps (CLOUD_PHASES, sky_params.h).
float shadow_texel_light(int i, float d)
{
	float ice = 0.0;
	if (CLOUD_PHASES != CLOUD_PHASES_ONE)
		ice = texelFetch(ShadowTex, 2 * SHADOW_W * SHADOW_W + i / 4)[i & 3];
	return exp(-shadow_texel_tau(texelFetch(ShadowTex, i), ice, d));
}

// The share of light (0 sun, 1 moon) the cloud lets through at q (km,
// the observer's east-north-up frame from the ground under it), from the
// light's map: each texel's transmittance, then bilinear between them (a
// texel at a cloud's edge holds cloud and gap, whose mean transmittance is
// the mean of the two, not exp of the mean optical depth); 1 outside the
// map (no cloud beyond the region).
float cloud_light(int light, vec3 q)
{
	ShadowFrame f = cloud_frame[light];
	float x = (dot(q, f.u.xyz) - f.U_MIN_KM) * f.U_TEXELS_PER_KM - 0.5;
	float y = (dot(q, f.v.xyz) - f.V_MIN_KM) * f.V_TEXELS_PER_KM - 0.5;
	float top = float(SHADOW_W) - 0.5;
	if (!(x > -0.5 && y > -0.5 && x < top && y < top))
		return 1.0;
	x = clamp(x, 0.0, float(SHADOW_W - 1));
	y = clamp(y, 0.0, float(SHADOW_W - 1));
	int i = min(int(x), SHADOW_W - 2), j = min(int(y), SHADOW_W - 2);
	float fx = x - float(i), fy = y - float(j);
	float d = f.PLANE_KM - dot(q, f.l.xyz);
	int base = light * SHADOW_W * SHADOW_W + j * SHADOW_W + i;
	float t00 = shadow_texel_light(base, d);
	float t10 = shadow_texel_light(base + 1, d);
	float t01 = shadow_texel_light(base + SHADOW_W, d);
	float t11 = shadow_texel_light(base + SHADOW_W + 1, d);
	return mix(mix(t00, t10, fx), mix(t01, t11, fx), fy);
}

// The share of the sky's multiply scattered light that reaches altitude
// h through the layers above it: skycloud_sky_occlusion's product over
// the layers, 1 - cover (1 - t), but with t the light a conservative slab
// lets through diffusely, 1 / (1 + 3/4 (1 - g) tau) (the two-stream under
// diffuse light), not exp(-tau): the sky's light scatters through a cloud,
// it is not taken away.
float cloud_sky_open(float h)
{
	if (CLOUD_LAYERS == 0)
		return 1.0;
	float open = 1.0;
	for (int i = 0; i < CLOUD_LAYERS; i++) {
		float above = skycloud_saturate((cloud_column[i].x - h) * cloud_column[i].y);
		float t = 1.0 / (1.0 + cloud_slab[i].x * cloud_column[i].z * above);
		open *= 1.0 - cloud_column[i].w * (1.0 - t);
	}
	return 1.0 - skycloud_saturate(1.0 - open);
}

// At a march step of altitude h: the sky the layers leave open for the
// multiply scattered light (cloud_ms_open) and the altitude that
// cloud_diffuse_source reads.
void cloud_at(float h)
{
	cloud_ms_open = cloud_sky_open(h);
	cloud_h_km = h;
}

// At a march step at q, altitude h: cloud_at(h), and the share of the
// sun's light the cloud lets through.
float cloud_step(vec3 q, float h)
{
	cloud_at(h);
	return cloud_light(0, q);
}

// The reflectance of a conservative slab of vertical optical depth tau
// (slab: cloud_slab's) for a beam at cos-zenith mu0 > 0: the
// delta-Eddington two-stream (Joseph, Wiscombe and Weinman 1976; Meador
// and Weaver 1980, the conservative case), held in [0, 1] (Eddington's
// goes slightly negative for a thin slab under a high light). beam: the
// delta-scaled beam it lets through, exp(-slab.y tau / mu0), which the
// caller has too.
float cloud_reflectance(float tau, vec2 slab, float mu0, float beam)
{
	float gt = slab.x * tau;
	float r = (gt + (0.5 - 0.75 * mu0) * (1.0 - beam)) / (1.0 + gt);
	return clamp(r, 0.0, 1.0);
}

// The light the layers scatter into the air at the step (cloud_at) for a
// light at cos-zenith mu_l there, per unit of its illuminance: under a
// layer, what it lets through diffusely (1 - R - exp(-(1 - g^2) tau / mu),
// the delta-scaled beam, forward peak included, being the shadow map's)
// as a uniform radiance from above,
// and the ground's reflection of it from below; over a layer, what the
// deck (cloud and ground) reflects beyond the ground alone, R (1 - A)^2 /
// (1 - R A), from below. Each a uniform hemisphere of radiance mu E x / pi,
// whose mean over the sphere is half of it, scattered as ms_source
// scatters the ground's bounce: sigma_s plus (below) or less (above) the
// ground's excess. Each layer alone, over its cover.
//
// cloud_diffuse_at sets the layers' terms (cloud_down, cloud_up: the
// shares from above and from below) for the light at the step;
// cloud_diffuse_source scales them by the light there. A sky-view
// invocation's columns share their steps, and their lights' cos-zenith
// differs by the tilt of the local vertical along the rays (a hundredth at
// 100 km): it sets the terms once a step for the columns' mean.
// over_all: a constant, true where the step is above every layer's top,
// so that no layer is above it and the light from above is compiled out.
void cloud_diffuse_at(float mu_l, bool over_all)
{
	cloud_down = vec3(0.0);
	cloud_up = vec3(0.0);
	if (!(mu_l > 0.0))
		return;
	vec3 albedo = GROUND_BLACK ? vec3(0.0) : P.albedo.rgb;
	for (int i = 0; i < CLOUD_LAYERS; i++) {
		vec4 col = cloud_column[i];
		float above = skycloud_saturate((col.x - cloud_h_km) * col.y);
		float ta = col.z * above, tb = col.z - ta;
		if (!over_all && ta > 0.0) {
			float beam = exp(-cloud_slab[i].y * ta / mu_l);
			float r = cloud_reflectance(ta, cloud_slab[i], mu_l, beam);
			vec3 d = col.w * max(1.0 - r - beam, 0.0) / (1.0 - r * albedo);
			cloud_down += d;
			cloud_up += albedo * d;
		}
		if (tb > 0.0) {
			float r = cloud_reflectance(tb, cloud_slab[i], mu_l, exp(-cloud_slab[i].y * tb / mu_l));
			cloud_up += col.w * r * (1.0 - albedo) * (1.0 - albedo) / (1.0 - r * albedo);
		}
	}
}

// The layers' light at the step for the light at cos-zenith mu_l, from
// cloud_diffuse_at's terms. t_l: the transmittance toward the light
// there, which the caller has looked up already.
vec3 cloud_diffuse_source(float mu_l, vec3 t_l, vec3 sigma_s, vec3 ground)
{
	if (!(mu_l > 0.0))
		return vec3(0.0);
	vec3 lit = t_l * (0.5 * mu_l / PI);
	return lit * ((sigma_s - ground) * cloud_down + (sigma_s + ground) * cloud_up);
}
