// skycloud.glsl - the cloud field in GLSL: proto/skycloud.h function for
// function (its float build), included by skyd's compute shaders and by
// render clients' shaders. The model: docs/clouds.md.
//
// Same names, arguments and conventions as skycloud.h (km, the observer's
// east-north-up frame, the wind's offset subtracted from the field
// coordinates); a layer is a SkycloudLayer filled on the CPU by
// skycloud_layer_init (the same fields in the same order, std430-packed:
// 4-byte scalars). Every float the noise, the coverage and the density
// compute is precise (no fused multiply-add), so that on a device whose
// +, -, * are correctly rounded (Vulkan requires it) they give the C
// function's bits; test_glsl_cloud checks it on the device. The altitude
// and the march use sqrt and the occlusion exp: within their ulps. Plain
// GLSL 4.50, no extensions, no bindings, no globals beyond constants.
#ifndef SKYCLOUD_GLSL
#define SKYCLOUD_GLSL

// skycloud.h's SKYCLOUD_VERSION.
#define SKYCLOUD_GLSL_VERSION 1

#define SKYCLOUD_MAX_LAYERS 4
#define SKYCLOUD_COVERAGE_OCTAVES 5
#define SKYCLOUD_DETAIL_OCTAVES 3
const float SKYCLOUD_PERIOD_KM = 1024.0;
const uint SKYCLOUD_STREAM_COVERAGE = 0x100u;
const uint SKYCLOUD_STREAM_DETAIL = 0x200u;
const float SKYCLOUD_DETAIL_GAIN = 1.5;

struct SkycloudLayer {
	int type;
	uint seed;
	uint index;
	float cover;
	float base_km, top_km;
	float inv_thickness_per_km;
	float threshold;
	float inv_edge;
	float inv_bottom_fade, inv_top_fade, anvil;
	float extinction_per_km;
	float erosion, inv_keep;
	float coverage_scale;
	float detail_scale;
	float profile_integral;
};

// pcg3d (Jarzynski and Olano 2020): integer only.
uvec3 skycloud_pcg3d(uvec3 v)
{
	v = v * 1664525u + 1013904223u;
	v.x += v.y * v.z;
	v.y += v.z * v.x;
	v.z += v.x * v.y;
	v ^= v >> 16u;
	v.x += v.y * v.z;
	v.y += v.z * v.x;
	v.z += v.x * v.y;
	return v;
}

uvec3 skycloud_key(uint seed, uint stream, uint octave)
{
	return skycloud_pcg3d(uvec3(seed, stream, octave));
}

uint skycloud_hash3(uint i, uint j, uint k, uvec3 key)
{
	return skycloud_pcg3d(uvec3(i, j, k) ^ key).x;
}

float skycloud_saturate(float x)
{
	return x < 0.0 ? 0.0 : x > 1.0 ? 1.0 : x;
}

float skycloud_wrap(float p)
{
	precise float f = floor(p * (1.0 / SKYCLOUD_PERIOD_KM));
	precise float r = p - SKYCLOUD_PERIOD_KM * f;
	return r;
}

// The lattice cell and the fraction in it, 16 bits of a cell: returns
// (i, i + 1) masked to the period, the fraction through t.
uvec2 skycloud_cell(float p, float s, out float t)
{
	precise float q = p * s * 65536.0;
	uint mask = uint(SKYCLOUD_PERIOD_KM * s) - 1u;
	uint u = uint(int(floor(q)));
	precise float f = float(u & 0xffffu) * (1.0 / 65536.0);
	t = f;
	return uvec2((u >> 16u) & mask, ((u >> 16u) + 1u) & mask);
}

float skycloud_fade(float t)
{
	precise float a = t * 6.0 - 15.0;
	precise float b = t * a + 10.0;
	precise float r = t * t * t * b;
	return r;
}

float skycloud_grad2(uint h, float x, float y)
{
	float gx = (h & 0x20000000u) != 0u ? 0.5 : 1.0;
	float gy = (h & 0x20000000u) != 0u ? 1.0 : 0.5;
	if ((h & 0x40000000u) != 0u)
		gx = -gx;
	if ((h & 0x80000000u) != 0u)
		gy = -gy;
	precise float r = gx * x + gy * y;
	return r;
}

float skycloud_grad3(uint h, float x, float y, float z)
{
	uint k = h >> 28u;
	float u = k < 8u ? x : y;
	float v = k < 4u ? y : (k == 12u || k == 14u) ? x : z;
	precise float r = ((k & 1u) != 0u ? -u : u) + ((k & 2u) != 0u ? -v : v);
	return r;
}

float skycloud_noise2(float x, float y, float s, uvec3 key)
{
	float tx, ty;
	uvec2 i = skycloud_cell(x, s, tx);
	uvec2 j = skycloud_cell(y, s, ty);
	precise float n00 = skycloud_grad2(skycloud_hash3(i.x, j.x, 0u, key), tx, ty);
	precise float n10 = skycloud_grad2(skycloud_hash3(i.y, j.x, 0u, key), tx - 1.0, ty);
	precise float n01 = skycloud_grad2(skycloud_hash3(i.x, j.y, 0u, key), tx, ty - 1.0);
	precise float n11 = skycloud_grad2(skycloud_hash3(i.y, j.y, 0u, key), tx - 1.0, ty - 1.0);
	precise float fx = skycloud_fade(tx), fy = skycloud_fade(ty);
	precise float a = n00 + fx * (n10 - n00);
	precise float b = n01 + fx * (n11 - n01);
	precise float r = a + fy * (b - a);
	return r;
}

float skycloud_noise3(float x, float y, float z, float s, uvec3 key)
{
	float tx, ty, tz;
	uvec2 i = skycloud_cell(x, s, tx);
	uvec2 j = skycloud_cell(y, s, ty);
	uvec2 k = skycloud_cell(z, s, tz);
	precise float fx = skycloud_fade(tx), fy = skycloud_fade(ty), fz = skycloud_fade(tz);
	precise float plane[2];
	for (int c = 0; c < 2; c++) {
		precise float dz = tz - float(c);
		uint kc = c == 0 ? k.x : k.y;
		precise float n00 = skycloud_grad3(skycloud_hash3(i.x, j.x, kc, key), tx, ty, dz);
		precise float n10 = skycloud_grad3(skycloud_hash3(i.y, j.x, kc, key), tx - 1.0, ty, dz);
		precise float n01 = skycloud_grad3(skycloud_hash3(i.x, j.y, kc, key), tx, ty - 1.0, dz);
		precise float n11 = skycloud_grad3(skycloud_hash3(i.y, j.y, kc, key), tx - 1.0, ty - 1.0, dz);
		precise float a = n00 + fx * (n10 - n00);
		precise float b = n01 + fx * (n11 - n01);
		plane[c] = a + fy * (b - a);
	}
	precise float r = plane[0] + fz * (plane[1] - plane[0]);
	return r;
}

// The coverage fBm at wrapped field coordinates.
float skycloud_coverage_fbm(SkycloudLayer L, float x, float y)
{
	precise float sum = 0.0, amp = 1.0, s = L.coverage_scale;
	for (uint o = 0u; o < uint(SKYCLOUD_COVERAGE_OCTAVES); o++) {
		uvec3 key = skycloud_key(L.seed, SKYCLOUD_STREAM_COVERAGE + L.index, o);
		precise float n = skycloud_noise2(x, y, s, key);
		sum += amp * n;
		amp *= 0.5;
		s *= 2.0;
	}
	return sum;
}

// (fBm - threshold) / edge at field coordinates (x, y) with the wind's
// offset: cloud where > 0.
float skycloud_coverage_margin(SkycloudLayer L, float x, float y, vec2 offset_km)
{
	precise float px = skycloud_wrap(x - offset_km.x), py = skycloud_wrap(y - offset_km.y);
	precise float m = (skycloud_coverage_fbm(L, px, py) - L.threshold) * L.inv_edge;
	return m;
}

float skycloud_coverage(SkycloudLayer L, float x, float y, vec2 offset_km)
{
	precise float m = skycloud_coverage_margin(L, x, y, offset_km) + 0.5;
	return skycloud_saturate(m);
}

// Billowy detail noise in [0, 1] at wrapped coordinates and altitude.
float skycloud_detail(SkycloudLayer L, float x, float y, float z)
{
	precise float sum = 0.0, amp = 1.0, s = L.detail_scale;
	for (uint o = 0u; o < uint(SKYCLOUD_DETAIL_OCTAVES); o++) {
		uvec3 key = skycloud_key(L.seed, SKYCLOUD_STREAM_DETAIL + L.index, o);
		precise float n = skycloud_noise3(x, y, z, s, key);
		sum += amp * (n < 0.0 ? -n : n);
		amp *= 0.5;
		s *= 2.0;
	}
	precise float r = sum * SKYCLOUD_DETAIL_GAIN;
	return skycloud_saturate(r);
}

float skycloud_profile(SkycloudLayer L, float hf)
{
	precise float pa = hf * L.inv_bottom_fade, pb = (1.0 - hf) * L.inv_top_fade;
	precise float a = skycloud_saturate(pa), b = skycloud_saturate(pb);
	precise float r = a * a * (3.0 - 2.0 * a) * (b * b * (3.0 - 2.0 * b));
	return r;
}

// Extinction per km of layer L at field coordinates (x, y) km, altitude h
// km: skycloud.h's skycloud_density.
float skycloud_density(SkycloudLayer L, float x, float y, float h, vec2 offset_km)
{
	precise float hf = (h - L.base_km) * L.inv_thickness_per_km;
	if (!(hf > 0.0 && hf < 1.0))
		return 0.0;
	precise float px = skycloud_wrap(x - offset_km.x), py = skycloud_wrap(y - offset_km.y);
	precise float m = (skycloud_coverage_fbm(L, px, py) - L.threshold) * L.inv_edge;
	precise float cm = m + 0.5 + L.anvil * hf * hf;
	precise float c = skycloud_saturate(cm);
	precise float e = c * skycloud_profile(L, hf);
	if (!(e > 0.0))
		return 0.0;
	precise float d = skycloud_detail(L, px, py, skycloud_wrap(h));
	precise float fe = (e - L.erosion * d) * L.inv_keep;
	precise float f = skycloud_saturate(fe);
	precise float r = L.extinction_per_km * (f < e ? f : e);
	return r;
}

float skycloud_density_all(SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], int n, float x, float y,
			   float h, vec2 offset_km)
{
	precise float sum = 0.0;
	for (int i = 0; i < n; i++) {
		precise float d = skycloud_density(layers[i], x, y, h, offset_km);
		sum += d;
	}
	return sum;
}

// The layers' occlusion of the sky from altitude h km, in [0, 1].
float skycloud_sky_occlusion(SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], int n, float h)
{
	float open = 1.0;
	for (int i = 0; i < n; i++) {
		SkycloudLayer L = layers[i];
		float above = skycloud_saturate((L.top_km - h) * L.inv_thickness_per_km);
		float tau = L.extinction_per_km * (L.top_km - L.base_km) * above * L.profile_integral;
		open *= 1.0 - L.cover * (1.0 - exp(-tau));
	}
	return skycloud_saturate(1.0 - open);
}

// Altitude above a planet of radius rb_km of p (east, north, up km).
float skycloud_altitude(float rb_km, vec3 p)
{
	float rho2 = p.x * p.x + p.y * p.y + p.z * (2.0 * rb_km + p.z);
	float r = sqrt(p.x * p.x + p.y * p.y + (rb_km + p.z) * (rb_km + p.z));
	return rho2 / (r + rb_km);
}

// The ray o + t d inside the sphere of radius rb + h_km: false if it
// misses.
bool skycloud_sphere(float rb_km, float h_km, vec3 o, vec3 d, out float t0, out float t1)
{
	vec3 c = vec3(o.xy, o.z + rb_km);
	float b = dot(c, d);
	float r = rb_km + h_km;
	float cc = dot(c, c) - r * r;
	float disc = b * b - cc;
	t0 = 0.0;
	t1 = 0.0;
	if (disc < 0.0)
		return false;
	float q = sqrt(disc);
	t0 = -b - q;
	t1 = -b + q;
	return true;
}

// Optical depth of the layers along o + t d up to max_km, midpoint rule
// in steps over the ray's near piece between the lowest base and the
// highest top: skycloud.h's skycloud_optical_depth.
float skycloud_optical_depth(SkycloudLayer layers[SKYCLOUD_MAX_LAYERS], int n, vec2 offset_km,
			     float rb_km, vec3 o, vec3 d, float max_km, int steps)
{
	float lo = 1e30, hi = -1e30;
	for (int i = 0; i < n; i++) {
		if (!(layers[i].cover > 0.0))
			continue;
		lo = min(lo, layers[i].base_km);
		hi = max(hi, layers[i].top_km);
	}
	float a0, a1, b0, b1;
	if (!(hi > lo) || steps < 1 || !skycloud_sphere(rb_km, hi, o, d, a0, a1))
		return 0.0;
	float t0 = max(a0, 0.0), t1 = min(a1, max_km);
	if (skycloud_sphere(rb_km, lo, o, d, b0, b1) && b1 > 0.0) {
		if (b0 > t0)
			t1 = min(b0, t1);
		else
			t0 = max(b1, t0);
	}
	if (!(t1 > t0))
		return 0.0;
	float dt = (t1 - t0) / float(steps), tau = 0.0;
	for (int k = 0; k < steps; k++) {
		float t = t0 + (float(k) + 0.5) * dt;
		vec3 p = o + t * d;
		tau += skycloud_density_all(layers, n, p.x, p.y, skycloud_altitude(rb_km, p), offset_km);
	}
	return tau * dt;
}

#endif
