// common.glsl - parameters, table storage and the physics every pass shares.
//
// Mirrors daemon/model.c (the double-precision oracle) and proto/skymap.h
// (the mappings): a change here is a change there. Lengths in km,
// coefficients in 1/km, directions in the observer's east-north-up frame
// with the planet centre at (0, 0, -(Rb + altitude)).


const float PI = 3.14159265358979;

// Specialization constants: what a scene does not need is compiled out.
layout(constant_id = 0) const int N_CONST = 3;        // constituents that are not all zero
layout(constant_id = 1) const int PHASE_0 = 1;        // 0 none, 1 Rayleigh, 2 Cornette-Shanks, 3 HG
layout(constant_id = 2) const int PHASE_1 = 2;
layout(constant_id = 3) const int PHASE_2 = 0;
layout(constant_id = 4) const int PHASE_3 = 0;
layout(constant_id = 5) const bool STORAGE_F16 = false;
layout(constant_id = 6) const bool MOON_LIT = false;
layout(constant_id = 7) const bool GROUND_BLACK = false;
layout(constant_id = 8) const int T_W = 256;
layout(constant_id = 9) const int T_H = 64;
layout(constant_id = 10) const int M_W = 32;
layout(constant_id = 11) const int M_H = 32;
layout(constant_id = 12) const int OUT_W = 1;
layout(constant_id = 13) const int OUT_H = 1;
layout(constant_id = 14) const int OUT_D = 1;
layout(constant_id = 15) const int STEPS = 1;
layout(constant_id = 17) const bool MULTISCATTER_ON = true;

struct Constituent {
	vec4 scattering;	// rgb 1/km, w = g
	vec4 absorption;	// rgb 1/km
	vec4 layer0;		// width_km, exp_term, exp_scale_per_km, linear_per_km
	vec4 layer0c_1;		// constant (layer 0), exp_term, exp_scale_per_km, linear_per_km (layer 1)
	vec4 layer1c;		// constant (layer 1)
};

layout(std140, binding = 0) uniform Params {
	vec4 planet;		// bottom radius, top radius, shell thickness, observer altitude
	vec4 albedo;		// ground albedo rgb
	vec4 sun_dir;		// unit, w unused
	vec4 sun_illum;		// lx per channel at the top of the atmosphere
	vec4 moon_dir;
	vec4 moon_illum;
	vec4 cam_fwd;		// w = tan(vfov / 2)
	vec4 cam_right;		// w = aspect
	vec4 cam_up;		// w = aerial range km
	vec4 misc;		// x horizon cos of the observer, y skyview min steps, z aerial squared (1/0)
	Constituent C[4];
} P;

layout(std430, binding = 1) buffer TransmittanceBuf { uint d[]; } TB;
layout(std430, binding = 2) buffer MultiscatterBuf { uint d[]; } MB;
layout(std430, binding = 3) buffer SkyviewBuf { uint d[]; } SB;
layout(std430, binding = 4) buffer AerialBuf { uint d[]; } AB;

// Texels are RGBA: four 32-bit words, or two words of packed halves.
#define LOAD_TEXEL(B, i) (STORAGE_F16 ? \
	vec4(unpackHalf2x16(B.d[2 * (i)]), unpackHalf2x16(B.d[2 * (i) + 1])) : \
	uintBitsToFloat(uvec4(B.d[4 * (i)], B.d[4 * (i) + 1], B.d[4 * (i) + 2], B.d[4 * (i) + 3])))

#define STORE_TEXEL(B, i, v) do { \
	if (STORAGE_F16) { \
		B.d[2 * (i)] = packHalf2x16((v).xy); \
		B.d[2 * (i) + 1] = packHalf2x16((v).zw); \
	} else { \
		uvec4 w_ = floatBitsToUint(v); \
		B.d[4 * (i)] = w_.x; B.d[4 * (i) + 1] = w_.y; \
		B.d[4 * (i) + 2] = w_.z; B.d[4 * (i) + 3] = w_.w; \
	} } while (false)

float safe_sqrt(float x) { return sqrt(max(x, 0.0)); }

// The exact unit <-> sub-texel pair of proto/skymap.h.
float unit_to_tex(float x, int n) { return 0.5 / float(n) + x * (1.0 - 1.0 / float(n)); }
float tex_to_unit(float u, int n) { return (u - 0.5 / float(n)) / (1.0 - 1.0 / float(n)); }

// r^2 - Rb^2 as h (2 Rb + h): exact at small altitudes.
float rho2(float h) { return h * (2.0 * P.planet.x + h); }
float horizon_cos(float h) { h = max(h, 0.0); return -safe_sqrt(rho2(h)) / (P.planet.x + h); }

float layer_density(vec4 a, float constant, float h)
{
	return clamp(a.y * exp(a.z * h) + a.w * h + constant, 0.0, 1.0);
}

float density(int i, float h)
{
	Constituent c = P.C[i];
	return h < c.layer0.x ? layer_density(c.layer0, c.layer0c_1.x, h)
			      : layer_density(vec4(0.0, c.layer0c_1.yzw), c.layer1c.x, h);
}

// sinh(x) / x, the exact mean of exp over a step whose exponent changes
// linearly by 2x: it makes a step over an exponential layer exact.
float sinhc(float x)
{
	float x2 = x * x;
	return x2 < 1e-2 ? 1.0 + x2 * (1.0 / 6.0 + x2 / 120.0) : sinh(x) / x;
}

// Mean density of constituent i over a step from altitude ha to hb, exact for
// exponential and linear terms when the altitude changes linearly.
float mean_density(int i, float ha, float hb)
{
	Constituent c = P.C[i];
	float hm = 0.5 * (ha + hb);
	vec4 l = hm < c.layer0.x ? c.layer0 : vec4(0.0, c.layer0c_1.yzw);
	float constant = hm < c.layer0.x ? c.layer0c_1.x : c.layer1c.x;
	float e = l.y * exp(l.z * hm) * sinhc(0.5 * l.z * (hb - ha));
	return clamp(e + l.w * hm + constant, 0.0, 1.0);
}

int phase_kind(int i) { return i == 0 ? PHASE_0 : i == 1 ? PHASE_1 : i == 2 ? PHASE_2 : PHASE_3; }

// Phase functions in 1/sr. The HG/CS denominator 1 + g^2 - 2 g mu is written
// (1 - g)^2 + 2 g (1 - mu), which does not cancel at g -> 1, mu -> 1.
float phase(int kind, float g, float mu)
{
	if (kind == 1)
		return 3.0 / (16.0 * PI) * (1.0 + mu * mu);
	float den = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu);
	float hg = (1.0 - g * g) / (4.0 * PI * den * sqrt(den));
	if (kind == 3)
		return hg;
	// Cornette-Shanks: HG times 3 (1 + mu^2) / (2 (2 + g^2)).
	return hg * 1.5 * (1.0 + mu * mu) / (2.0 + g * g);
}

struct Medium {
	vec3 scattering;	// total, 1/km
	vec3 extinction;	// total, 1/km
	vec3 absorption;
};

Medium medium(float h)
{
	Medium m;
	m.scattering = vec3(0.0);
	m.absorption = vec3(0.0);
	for (int i = 0; i < N_CONST; i++) {
		float d = density(i, h);
		m.scattering += d * P.C[i].scattering.rgb;
		m.absorption += d * P.C[i].absorption.rgb;
	}
	m.extinction = m.scattering + m.absorption;
	return m;
}

// Integral over a segment of length dt of exp(-sigma t): (1 - exp(-sigma dt)) / sigma,
// computed without cancellation when sigma dt is small and without 0/0 at sigma = 0.
vec3 segment_weight(vec3 sigma, float dt)
{
	vec3 x = sigma * dt;
	vec3 series = dt * (1.0 - x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0))));
	vec3 direct = (1.0 - exp(-x)) / max(sigma, vec3(1e-30));
	return mix(direct, series, lessThan(x, vec3(0.02)));
}

// Altitude of the point at distance t along direction cos-zenith mu from a
// point at altitude h: (r_t^2 - Rb^2) / (r_t + Rb), no cancellation.
float altitude_along(float h, float mu, float t, out float ret_r)
{
	float rb = P.planet.x, r = rb + h;
	float excess = rho2(h) + t * (t + 2.0 * r * mu);
	ret_r = sqrt(rb * rb + max(excess, 0.0));
	return excess / (ret_r + rb);
}

// Distance from altitude h (inside the shell) to the top along mu.
float distance_to_top(float h, float mu)
{
	float rb = P.planet.x, r = rb + h, shell = P.planet.z;
	float c = (shell - h) * (2.0 * rb + shell + h);	// rt^2 - r^2 >= 0
	return max(-r * mu + safe_sqrt(r * r * mu * mu + c), 0.0);
}

// Whether a ray from altitude h along mu hits the ground, and where: the
// caller decides the switch from the horizon cosine, never from a
// discriminant near 0.
bool hits_ground(float h, float mu, out float ret_t)
{
	float mu_h = horizon_cos(h);
	ret_t = 0.0;
	if (h < 0.0 || mu >= mu_h)
		return false;
	float r = P.planet.x + h;
	float disc = r * r * (mu - mu_h) * (mu + mu_h);
	ret_t = max(-r * mu - safe_sqrt(disc), 0.0);
	return true;
}

// Bilinear, clamp to edge, on a W x H RGBA table.
#define BILINEAR(B, W, H, uv, ret) do { \
	vec2 p_ = clamp(uv, vec2(0.0), vec2(1.0)) * vec2(W, H) - 0.5; \
	vec2 f_ = fract(p_); ivec2 i_ = ivec2(floor(p_)); \
	int x0_ = clamp(i_.x, 0, W - 1), x1_ = clamp(i_.x + 1, 0, W - 1); \
	int y0_ = clamp(i_.y, 0, H - 1), y1_ = clamp(i_.y + 1, 0, H - 1); \
	vec4 a_ = LOAD_TEXEL(B, y0_ * W + x0_), b_ = LOAD_TEXEL(B, y0_ * W + x1_); \
	vec4 c_ = LOAD_TEXEL(B, y1_ * W + x0_), d_ = LOAD_TEXEL(B, y1_ * W + x1_); \
	ret = mix(mix(a_, b_, f_.x), mix(c_, d_, f_.x), f_.y); } while (false)

vec2 transmittance_uv(float h, float mu)
{
	float rb = P.planet.x, shell = P.planet.z;
	h = clamp(h, 0.0, shell);
	float H = sqrt(shell * (2.0 * rb + shell));
	float rho = safe_sqrt(rho2(h));
	float d = distance_to_top(h, clamp(mu, -1.0, 1.0));
	float d_min = shell - h, d_max = rho + H;
	float x_mu = d_max > d_min ? (d - d_min) / (d_max - d_min) : 0.0;
	return vec2(unit_to_tex(clamp(x_mu, 0.0, 1.0), T_W), unit_to_tex(clamp(rho / H, 0.0, 1.0), T_H));
}

// Transmittance from altitude h towards cos-zenith mu, to the top of the
// atmosphere; 0 when the ray hits the ground (the planet's shadow).
vec3 transmittance_to_top(float h, float mu)
{
	float t;
	if (hits_ground(h, mu, t))
		return vec3(0.0);
	vec4 v;
	BILINEAR(TB, T_W, T_H, transmittance_uv(h, mu), v);
	return v.rgb;
}

vec3 multiscatter(float h, float mu_s)
{
	// skymap.h: u packs texels around the horizon of the altitude.
	h = clamp(h, 0.0, P.planet.z);
	float mh = horizon_cos(h), d = clamp(mu_s, -1.0, 1.0) - mh;
	float sn = clamp(d < 0.0 ? d / (1.0 + mh) : d / (1.0 - mh), -1.0, 1.0);
	vec2 uv = vec2(unit_to_tex(0.5 + 0.5 * sign(sn) * sqrt(abs(sn)), M_W),
		       unit_to_tex(h / P.planet.z, M_H));
	vec4 v;
	BILINEAR(MB, M_W, M_H, uv, v);
	return v.rgb;
}

// The phase of every constituent for one light: constant along a view ray
// towards a distant light, so it is evaluated once per ray, not per step.
struct Phases {
	float p[4];
};

Phases ray_phases(vec3 view_dir, vec3 light_dir)
{
	Phases ph;
	float mu = dot(view_dir, light_dir);
	for (int i = 0; i < 4; i++)
		ph.p[i] = i < N_CONST && phase_kind(i) != 0 ? phase(phase_kind(i), P.C[i].scattering.w, mu) : 0.0;
	return ph;
}

// One step of a view ray: the medium and the phase-weighted scattering for
// the sun and the moon, every density evaluated once.
struct Step {
	Medium m;
	vec3 phased_sun;
	vec3 phased_moon;
};

Step sample_step(float h, Phases sun, Phases moon)
{
	Step st;
	st.m.scattering = vec3(0.0);
	st.m.absorption = vec3(0.0);
	st.phased_sun = vec3(0.0);
	st.phased_moon = vec3(0.0);
	for (int i = 0; i < N_CONST; i++) {
		float d = density(i, h);
		vec3 s = d * P.C[i].scattering.rgb;
		st.m.scattering += s;
		st.m.absorption += d * P.C[i].absorption.rgb;
		st.phased_sun += s * sun.p[i];
		if (MOON_LIT)
			st.phased_moon += s * moon.p[i];
	}
	st.m.extinction = st.m.scattering + st.m.absorption;
	return st;
}

// In-scattered radiance source at a point for one light: single scattering
// through each constituent's phase plus Hillaire's isotropic higher orders.
vec3 light_source(float h, vec3 up, vec3 light_dir, vec3 illum, vec3 phased, vec3 sigma_s)
{
	float mu_l = dot(up, light_dir);
	vec3 s = phased * transmittance_to_top(h, mu_l);
	if (MULTISCATTER_ON)
		s += sigma_s * multiscatter(h, mu_l);
	return s * illum;
}

struct March {
	vec3 radiance;
	vec3 optical_depth;
};

// The part of a ray from the observer (altitude h0, direction dir in ENU)
// inside the shell and above the ground: [t0, t1]; false if none.
bool ray_in_shell(float h0, vec3 dir, out float t0, out float t1)
{
	float rb = P.planet.x, shell = P.planet.z, mu = dir.z;
	float r = rb + h0;
	t0 = 0.0;
	t1 = 0.0;
	if (h0 > shell) {
		// From space: enter the top sphere, if the ray reaches it.
		float c = (h0 - shell) * (2.0 * rb + h0 + shell);	// r^2 - rt^2 > 0
		float disc = r * r * mu * mu - c;
		if (mu >= 0.0 || disc <= 0.0)
			return false;
		float s = sqrt(disc);
		t0 = -r * mu - s;
		t1 = -r * mu + s;
	} else {
		t1 = distance_to_top(max(h0, 0.0), mu);
	}
	float tg;
	float hh = max(h0, 0.0);
	if (h0 <= shell) {
		if (hits_ground(hh, mu, tg))
			t1 = tg;
	} else {
		// Ground hit from space, solved at the entry point.
		float ra;
		float he = altitude_along(h0, mu, t0, ra);
		float mue = (r * mu + t0) / ra;
		if (hits_ground(he, mue, tg))
			t1 = t0 + tg;
	}
	return t1 > t0;
}
