// common.glsl - parameters, table storage and the physics every pass shares.
//
// Mirrors truth/model.c (the double-precision oracle); the uv mappings are
// proto/glsl/skymap.glsl, the file render clients include too (checked
// against proto/skymap.h by test_glsl_map). Lengths in km, coefficients in
// 1/km, directions in the observer's east-north-up frame with the planet
// centre at (0, 0, -(Rb + altitude)).

#include "sky_params.h"
#include "skymap.glsl"

const float PI = 3.14159265358979;

// Specialization constants: what a scene does not need is compiled out.
layout(constant_id = SPEC_N_CONST) const int N_CONST = 3;        // constituents that are not all zero
layout(constant_id = SPEC_PHASE_0) const int PHASE_0 = 1;        // 0 none, 1 Rayleigh, 2 Cornette-Shanks, 3 HG
layout(constant_id = SPEC_PHASE_1) const int PHASE_1 = 2;
layout(constant_id = SPEC_PHASE_2) const int PHASE_2 = 0;
layout(constant_id = SPEC_PHASE_3) const int PHASE_3 = 0;
layout(constant_id = SPEC_STORAGE_F16) const bool STORAGE_F16 = false;
layout(constant_id = SPEC_MOON_LIT) const bool MOON_LIT = false;
layout(constant_id = SPEC_GROUND_BLACK) const bool GROUND_BLACK = false;
layout(constant_id = SPEC_T_W) const int T_W = 256;
layout(constant_id = SPEC_T_H) const int T_H = 64;
layout(constant_id = SPEC_M_W) const int M_W = 32;
layout(constant_id = SPEC_M_H) const int M_H = 32;
layout(constant_id = SPEC_OUT_W) const int OUT_W = 1;
layout(constant_id = SPEC_OUT_H) const int OUT_H = 1;
layout(constant_id = SPEC_OUT_D) const int OUT_D = 1;
layout(constant_id = SPEC_STEPS) const int STEPS = 1;
layout(constant_id = SPEC_MULTISCATTER_ON) const bool MULTISCATTER_ON = true;
layout(constant_id = SPEC_EXP_MASK) const int EXP_MASK = 15;      // bit i: constituent i has an exponential term
// (SPEC_MS_DIRS, SPEC_MS_SUN_GROUP: msgrid.glsl; SPEC_SV_AZ_GROUP: skyview.comp;
// SPEC_ITER_FIRST: msiterate.comp.)
layout(constant_id = SPEC_MOMENT_LOBE) const int MOMENT_LOBE = 0;    // 1 + the constituent whose phase sees the lobe (ms_source), 0 none
const int MOMENT_CONST = MOMENT_LOBE - 1;
layout(constant_id = SPEC_DELTA_LOBE) const int DELTA_LOBE = 0;     // 1 + the constituent delta-M scaled for the higher orders (delta_source), 0 none
const int DELTA_CONST = DELTA_LOBE - 1;
layout(constant_id = SPEC_LOOKUP_IMAGES) const bool LOOKUP_IMAGES = false;	// the lookups through sampled images
layout(constant_id = SPEC_MS_UNIFORM) const bool MS_UNIFORM = false;	// multi-scattering through MU
layout(constant_id = SPEC_CLOUD_LAYERS) const int CLOUD_LAYERS = 0;	// cloud layers drawn (clouds.glsl); 0: no cloud term

// The share of the sky's multiply scattered light that the cloud layers
// above the marched point let through (cloud_sky_open in clouds.glsl):
// sky-view and aerial set it at each step where CLOUD_LAYERS > 0.
float cloud_ms_open = 1.0;

// struct Constituent and struct Params: sky_params.h.
layout(std140, binding = BINDING_PARAMS) uniform ParamsBlock { Params params; };

// A private copy that every main() makes first (load_params()): lavapipe's
// LLVM passes do no loop-invariant code motion, so each read of the uniform
// block inside a loop would be a fresh load; the copy lives in registers.
// The same holds for any loop-invariant expression: hoist it by hand.
Params P;

void load_params() { P = params; }

// The ground's first bounce through each constituent's phase
// (phase_ground_excess in daemon/engine/phase.c): k - 1 for a view of
// cos-zenith mu_view at the scattering point, a component per constituent.
// The multi-scattering table carries the sunlit ground's light as an
// isotropic share of psi_ms (its A), but a forward-peaked phase sends
// little of that upwelling light to a viewer looking up and much to one
// looking down. A polynomial in sqrt|mu| (phase_ground_fit, powers 2 to 9),
// because a table read with a different index in every lane is slow on
// lavapipe.
const int GROUND_FIT = SKY_GROUND_FIT;

vec4 ground_excess(float mu_view)
{
	float s = sqrt(min(abs(mu_view), 1.0));
	vec4 e = P.ground_fit[GROUND_FIT - 1];
	for (int j = GROUND_FIT - 2; j >= 0; j--)
		e = e * s + P.ground_fit[j];
	e *= s * s;
	return mu_view < 0.0 ? -e : e;
}

layout(std430, binding = BINDING_TRANSMITTANCE) buffer TransmittanceBuf { uint d[]; } TB;
layout(std430, binding = BINDING_MULTISCATTER) buffer MultiscatterBuf { uint d[]; } MB;
layout(std430, binding = BINDING_SKYVIEW) buffer SkyviewBuf { uint d[]; } SB;
layout(std430, binding = BINDING_AERIAL) buffer AerialBuf { uint d[]; } AB;
// The same transmittance and multi-scattering memory, read through texel
// buffers (float32 RGBA): the gathers are vectorized.
layout(binding = BINDING_TRANSMITTANCE_TEX) uniform samplerBuffer TransmittanceTex;
layout(binding = BINDING_MULTISCATTER_TEX) uniform samplerBuffer MultiscatterTex;
// And as a uniform block where MS_UNIFORM (aerial perspective on a CPU):
// llvmpipe calls out for every texel-buffer fetch, spilling its vector
// registers, but loads a uniform block inline.
layout(std140, binding = BINDING_MULTISCATTER_UBO) uniform MultiscatterBlock {
	vec4 t[SKY_MS_UNIFORM_TEXELS];
} MU;
// And as sampled images, bilinear by the texture units at texel
// coordinates (texel i's centre at i + 0.5), where LOOKUP_IMAGES: the
// engine copies the tables into them (eng_pass.c).
layout(binding = BINDING_TRANSMITTANCE_IMG) uniform sampler2D TransmittanceImg;
layout(binding = BINDING_MULTISCATTER_IMG) uniform sampler2D MultiscatterImg;
// Column densities of the transmittance texels, one per constituent
// (columns.comp): internal, float32 whatever the tables' storage.
layout(std430, binding = BINDING_COLUMNS) buffer ColumnBuf { vec4 d[]; } CB;
// The same memory as a lookup (delta-M's scaled transmittance).
layout(binding = BINDING_COLUMNS_TEX) uniform samplerBuffer ColumnTex;
// The shape of the multiply scattered light (multiscatter.comp, with a lobe
// constituent): a texel per multi-scattering texel, float32, internal. Written
// through the storage buffer, read through the texel buffer.
layout(std430, binding = BINDING_MOMENT) buffer MomentBuf { vec4 d[]; } MOB;
layout(binding = BINDING_MOMENT_TEX) uniform samplerBuffer MomentTex;

// Texels are RGBA float32, four 32-bit words, whatever the storage: with
// storage=f16 the pack pass (pack.comp) writes the published binary16 copy.
#define STORE_TEXEL(B, i, v) do { \
	uvec4 w_ = floatBitsToUint(v); \
	B.d[4 * (i)] = w_.x; B.d[4 * (i) + 1] = w_.y; \
	B.d[4 * (i) + 2] = w_.z; B.d[4 * (i) + 3] = w_.w; \
	} while (false)

// With storage=f16 the passes also find the largest |RGB| they store,
// which pack.comp scales the binary16 copy by: each invocation keeps the
// largest magnitude's float bits (non-negative floats order as their bits;
// NaN above infinity) and adds them to its table's with one atomicMax.
layout(std430, binding = BINDING_PACK) buffer PackBuf {
	uint texels[SKY_PACK_TABLES];
	uint max_bits[SKY_PACK_TABLES];
	int scale_log2[SKY_PACK_TABLES];
} PB;

uint range_bits = 0u;

void note_range(vec3 rgb)
{
	if (STORAGE_F16) {
		uvec3 b = floatBitsToUint(rgb) & 0x7fffffffu;
		range_bits = max(range_bits, max(b.x, max(b.y, b.z)));
	}
}

// table: in state_table order, the table's binding less BINDING_TRANSMITTANCE.
void flush_range(int table)
{
	if (STORAGE_F16 && range_bits != 0u)
		atomicMax(PB.max_bits[table], range_bits);
}

// The table row that invocation row gy of n computes: rows from both ends
// in turn. lavapipe hands each of its threads a contiguous share of the
// workgroups, so where a row's cost grows from one end of the table to the
// other (altitude, the horizon) each share gets half of each end and the
// threads finish together; a GPU does not care. Rows past n stay past it.
int interleaved_row(int gy, int n)
{
	if (gy >= n)
		return gy;
	return (gy & 1) == 0 ? gy >> 1 : n - 1 - (gy >> 1);
}

// skymap.glsl's, at this planet.
float safe_sqrt(float x) { return skymap_safe_sqrt(x); }
float tex_to_unit(float u, int n) { return skymap_tex_to_unit(u, n); }
float rho2(float h) { return skymap_rho2(P.BOTTOM_RADIUS_KM, h); }
float horizon_cos(float h) { return skymap_horizon_cos(P.BOTTOM_RADIUS_KM, h); }

// Layer 0 below its width, layer 1 above: (exp_term, exp_scale_per_km,
// linear_per_km, constant), so that one exp() serves either layer.
vec4 layer_at(Constituent c, float h)
{
	return h < c.LAYER0_WIDTH_KM ? vec4(c.layer0.yzw, c.LAYER0_CONSTANT)
				     : vec4(c.layer0c_1.yzw, c.LAYER1_CONSTANT);
}

float density(int i, float h)
{
	vec4 l = layer_at(P.c[i], h);
	float e = (EXP_MASK & (1 << i)) != 0 ? l.x * exp(l.y * h) : 0.0;
	return clamp(e + l.z * h + l.w, 0.0, 1.0);
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
		m.scattering += d * P.c[i].scattering.rgb;
		m.absorption += d * P.c[i].absorption.rgb;
	}
	m.extinction = m.scattering + m.absorption;
	return m;
}

// One step of length dt through extinction sigma: its transmittance
// exp(-sigma dt) in ret_step_t, and the integral of exp(-sigma t) over it,
// (1 - exp(-sigma dt)) / sigma, from the same exp(), without cancellation when
// sigma dt is small and without 0/0 at sigma = 0. Marches carry the product
// of the steps' transmittances rather than exp() of a running optical depth.
vec3 step_weight(vec3 sigma, float dt, out vec3 ret_step_t)
{
	vec3 x = sigma * dt;
	ret_step_t = exp(-x);
	vec3 series = dt * (1.0 - x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0))));
	vec3 direct = (1.0 - ret_step_t) / max(sigma, vec3(1e-30));
	return mix(direct, series, lessThan(x, vec3(0.02)));
}

// Altitude of the point at distance t along direction cos-zenith mu from a
// point at altitude h: (r_t^2 - Rb^2) / (r_t + Rb), no cancellation.
float altitude_along(float h, float mu, float t, out float ret_r)
{
	float rb = P.BOTTOM_RADIUS_KM, r = rb + h;
	float excess = rho2(h) + t * (t + 2.0 * r * mu);
	ret_r = sqrt(rb * rb + max(excess, 0.0));
	return excess / (ret_r + rb);
}

// Distance from altitude h (inside the shell) to the top along mu.
float distance_to_top(float h, float mu)
{
	float rb = P.BOTTOM_RADIUS_KM, r = rb + h, shell = P.SHELL_KM;
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
	float r = P.BOTTOM_RADIUS_KM + h;
	float disc = r * r * (mu - mu_h) * (mu + mu_h);
	ret_t = max(-r * mu - safe_sqrt(disc), 0.0);
	return true;
}

// Bilinear lookups on W x H RGBA texel buffers. With the sub-texel mapping
// of proto/skymap.h a unit coordinate x sits at texel position x (n - 1), so
// an axis needs no edge clamp beyond the last texel.
struct Axis {
	int i0, i1;
	float f;
};

Axis axis(float x, int n)
{
	Axis a;
	float p = clamp(x, 0.0, 1.0) * float(n - 1), fl = floor(p);
	a.i0 = int(fl);
	a.i1 = min(a.i0 + 1, n - 1);
	a.f = p - fl;
	return a;
}

// The row axis is the caller's, shared between lookups at one altitude.
vec4 bilinear(samplerBuffer tex, int w, float x, Axis rows)
{
	Axis c = axis(x, w);
	int r0 = rows.i0 * w, r1 = rows.i1 * w;
	vec4 a = mix(texelFetch(tex, r0 + c.i0), texelFetch(tex, r0 + c.i1), c.f);
	vec4 b = mix(texelFetch(tex, r1 + c.i0), texelFetch(tex, r1 + c.i1), c.f);
	return mix(a, b, rows.f);
}

// What the lookups at altitude h share between directions: the texel rows
// of both tables, the horizon and the distances that bound the mapping.
struct TAlt {
	float h, r, mu_horizon;
	Axis t_rows;		// the altitude's rows in the transmittance table
	Axis ms_rows;		// and in the multi-scattering table,
	vec2 ms_horizon;	// whose u packs texels around each row's horizon cosine
	vec2 ms_below, ms_above;	// 1 / (1 + mu_horizon), 1 / (1 - mu_horizon)
	float top_c;		// top^2 - r^2
	float d_min, inv_range;	// x_mu = (d - d_min) * inv_range
};

TAlt t_alt(float h)
{
	float rb = P.BOTTOM_RADIUS_KM, shell = P.SHELL_KM;
	TAlt a;
	a.h = clamp(h, 0.0, shell);
	a.r = rb + a.h;
	float H = P.TOP_DISTANCE_KM;
	float rho = safe_sqrt(rho2(a.h));
	// Below the ground (rounding at a ray's end) nothing is in the way, as
	// in hits_ground().
	a.mu_horizon = h < 0.0 ? -2.0 : -rho / a.r;
	a.t_rows = axis(rho / H, T_H);
	a.ms_rows = axis(h / shell, M_H);
	// Each row is read at its own altitude's u for mu_s (multiscatter_at).
	vec2 hr = vec2(float(a.ms_rows.i0), float(a.ms_rows.i1)) * (shell / float(M_H - 1));
	a.ms_horizon = vec2(horizon_cos(hr.x), horizon_cos(hr.y));
	a.ms_below = 1.0 / (1.0 + a.ms_horizon);
	a.ms_above = 1.0 / (1.0 - a.ms_horizon);
	a.top_c = (shell - a.h) * (2.0 * rb + shell + a.h);
	a.d_min = shell - a.h;
	float d_max = rho + H;
	a.inv_range = d_max > a.d_min ? 1.0 / (d_max - a.d_min) : 0.0;
	return a;
}

// The transmittance table's unit coordinate along a row for cos-zenith mu
// from the altitude of a (Bruneton's mapping of the distance to the top).
float transmittance_x(TAlt a, float mu)
{
	return skymap_transmittance_x(a.r, mu, a.top_c, a.d_min, a.inv_range);
}

// Transmittance to the top of the atmosphere along mu, whether or not the
// planet is in the way.
vec3 transmittance_lookup(TAlt a, float mu)
{
	if (LOOKUP_IMAGES) {
		float x = clamp(transmittance_x(a, mu), 0.0, 1.0) * float(T_W - 1);
		return textureLod(TransmittanceImg, vec2(x, float(a.t_rows.i0) + a.t_rows.f) + 0.5, 0.0).rgb;
	}
	return bilinear(TransmittanceTex, T_W, transmittance_x(a, mu), a.t_rows).rgb;
}

// Transmittance from the altitude of a towards cos-zenith mu, to the top of
// the atmosphere; 0 when the ray hits the ground (the planet's shadow).
vec3 transmittance_at(TAlt a, float mu)
{
	return mu < a.mu_horizon ? vec3(0.0) : transmittance_lookup(a, mu);
}

// The light that reaches a point from a sun or moon of angular radius
// radius_rad: a disk, not a point, so the planet's shadow covers it
// gradually as its centre crosses the horizon (the fraction above it as in
// Bruneton 2017: a smoothstep over the radius, in cosine units at the
// horizon). A point light would switch each sample of a march on or off
// and the sky would brighten in steps as the sun sets.
float light_visible(TAlt a, float mu, float radius_rad)
{
	float e = P.BOTTOM_RADIUS_KM / a.r * radius_rad, x = mu - a.mu_horizon;
	return e > 0.0 ? smoothstep(-e, e, x) : (x < 0.0 ? 0.0 : 1.0);
}

vec3 light_transmittance(TAlt a, float mu, float radius_rad)
{
	float visible = light_visible(a, mu, radius_rad);
	return visible > 0.0 ? visible * transmittance_lookup(a, mu) : vec3(0.0);
}

// The same visible fraction averaged over a whole march step rather than
// taken at its midpoint: x_a and x_b are mu - mu_horizon (the light's
// height over the local horizon, in cosine units) at the step's two ends,
// taken linear in between, e the disk's half-width in those units. On a
// small planet the horizon dips by degrees along one step, so a midpoint
// sample switched the step's whole contribution on within a fraction of a
// degree of the light and the sky brightened in stairs as the sun set; the
// mean moves the shadow's edge continuously through the step. With
// V = smoothstep(-e, e, x) and k = (x / e + 1) / 2, the integral of
// 3 k^2 - 2 k^3 over [k_lo, k_hi] is (k_hi - k_lo) G with
// G = k_hi^2 + k_hi k_lo + k_lo^2 - (k_hi + k_lo) (k_hi^2 + k_lo^2) / 2,
// factored so that a short step does not cancel; G(k, k) = V. half_inv_e
// is 0.5 / e, shared by the columns of a step; for a point light (e = 0)
// pass 1e30: k is then 0 or 1 and G the step function.
float disk_visible_mean(float xa, float xb, float e, float half_inv_e)
{
	// Branch-free: lavapipe runs both sides of a branch for its lanes. The
	// step's parts fully lit (above) and in the penumbra (inside), the
	// latter weighted by G; a step of zero length is G itself, the
	// smoothstep at the point.
	float lo = min(xa, xb), hi = max(xa, xb), d = hi - lo;
	float above = max(hi, e) - max(lo, e), inside = clamp(hi, -e, e) - clamp(lo, -e, e);
	float kl = clamp(0.5 + lo * half_inv_e, 0.0, 1.0), kh = clamp(0.5 + hi * half_inv_e, 0.0, 1.0);
	float g = kh * kh + kh * kl + kl * kl - 0.5 * (kh + kl) * (kh * kh + kl * kl);
	return d > 0.0 ? (inside * g + above) / d : g;
}

// skymap.h: u packs texels around the horizon of the row's altitude. The
// two rows are read at the same mu_s, each at its own u, and blended in
// altitude: one u for both would read the lower row at a sun higher above
// the earth's shadow than the point's (mu_h grows as sqrt(h) between rows)
// and brighten the sky in the shadow near the horizon.
// The four texels a multi-scattering lookup blends (i: the lower row's
// two, the upper row's two) and the weights (x, y: within each row; z:
// between the rows).
struct MsTaps {
	ivec4 i;
	vec3 f;
	vec4 at;	// texel coordinates: the lower row's, the upper row's
};

// A row's u for mu_s: the row's horizon cosine mh and 1 / (1 + mh),
// 1 / (1 - mh), the scales below and above it.
float ms_u(float mu_s, float mh, float below, float above)
{
	return skymap_multiscatter_x(mu_s, mh, below, above);
}

MsTaps ms_taps(TAlt a, float mu_s)
{
	Axis c0 = axis(ms_u(mu_s, a.ms_horizon.x, a.ms_below.x, a.ms_above.x), M_W);
	Axis c1 = axis(ms_u(mu_s, a.ms_horizon.y, a.ms_below.y, a.ms_above.y), M_W);
	int r0 = a.ms_rows.i0 * M_W, r1 = a.ms_rows.i1 * M_W;
	MsTaps t;
	t.i = ivec4(r0 + c0.i0, r0 + c0.i1, r1 + c1.i0, r1 + c1.i1);
	t.f = vec3(c0.f, c1.f, a.ms_rows.f);
	t.at = vec4(float(c0.i0) + c0.f, float(a.ms_rows.i0), float(c1.i0) + c1.f, float(a.ms_rows.i1)) + 0.5;
	return t;
}

vec4 ms_read(samplerBuffer tex, MsTaps t)
{
	return mix(mix(texelFetch(tex, t.i.x), texelFetch(tex, t.i.y), t.f.x),
		   mix(texelFetch(tex, t.i.z), texelFetch(tex, t.i.w), t.f.y), t.f.z);
}

// ms_read of the multi-scattering table: by hand, or each row by the
// texture units (a row's centre: no blend across rows) and then the rows.
vec4 ms_read_table(MsTaps t)
{
	if (LOOKUP_IMAGES)
		return mix(textureLod(MultiscatterImg, t.at.xy, 0.0), textureLod(MultiscatterImg, t.at.zw, 0.0), t.f.z);
	if (MS_UNIFORM)
		return mix(mix(MU.t[t.i.x], MU.t[t.i.y], t.f.x),
			   mix(MU.t[t.i.z], MU.t[t.i.w], t.f.y), t.f.z);
	return ms_read(MultiscatterTex, t);
}

vec4 multiscatter_at(TAlt a, float mu_s)
{
	return ms_read_table(ms_taps(a, mu_s));
}

// The Legendre moments g1, g2 through which the lobe constituent scatters
// the shape of the multiply scattered light (ms_source).
vec2 ms_lobe_moments()
{
	vec2 g = vec2(P.c[max(MOMENT_CONST, 0)].PHASE_G1, P.c[max(MOMENT_CONST, 0)].PHASE_G2);
	// With delta-M the field is the scaled medium's, scattered by the
	// truncated phase: Henyey-Greenstein g', moments g' and g'^2.
	if (DELTA_CONST >= 0)
		g = vec2(P.c[max(DELTA_CONST, 0)].DELTA_G, P.c[max(DELTA_CONST, 0)].DELTA_G * P.c[max(DELTA_CONST, 0)].DELTA_G);
	return g;
}

// The phase of every constituent for one light: constant along a view ray
// towards a distant light, so it is evaluated once per ray, not per step;
// so is the aureole's lobe seen at the view's angle to the light, 4 pi HG
// - 1 at g1 g1 (ms_source), a square root and a division per column-step
// of sky-view otherwise.
struct Phases {
	float p[4];
	float mu;		// the view's cosine with the light
	float ms_lobe;		// 4 pi HG(g1 g1, mu) - 1; 0 without a lobe constituent
};

Phases ray_phases(vec3 view_dir, vec3 light_dir)
{
	Phases ph;
	float mu = dot(view_dir, light_dir);
	for (int i = 0; i < 4; i++)
		ph.p[i] = i < N_CONST && phase_kind(i) != 0 ? phase(phase_kind(i), P.c[i].PHASE_G, mu) : 0.0;
	ph.mu = mu;
	ph.ms_lobe = 0.0;
	if (MOMENT_CONST >= 0) {
		float gl = ms_lobe_moments().x * ms_lobe_moments().x;
		float den = (1.0 - gl) * (1.0 - gl) + 2.0 * gl * (1.0 - mu);
		ph.ms_lobe = (1.0 - gl * gl) / (den * sqrt(den)) - 1.0;
	}
	return ph;
}

// The scattering of each constituent at a point, every density evaluated
// once, kept apart so that each light's phases (per column of a sky-view
// row), the ground's phase factor and delta-M weigh it after the fact.
struct Scatter {
	vec3 s[4];
};

Medium medium_parts(float h, out Scatter ret)
{
	Medium m;
	m.scattering = vec3(0.0);
	m.absorption = vec3(0.0);
	for (int i = 0; i < 4; i++)
		ret.s[i] = vec3(0.0);
	for (int i = 0; i < N_CONST; i++) {
		float d = density(i, h);
		ret.s[i] = d * P.c[i].scattering.rgb;
		m.scattering += ret.s[i];
		m.absorption += d * P.c[i].absorption.rgb;
	}
	m.extinction = m.scattering + m.absorption;
	return m;
}

vec3 phased(Scatter sc, Phases ph)
{
	vec3 r = vec3(0.0);
	for (int i = 0; i < N_CONST; i++)
		r += sc.s[i] * ph.p[i];
	return r;
}

// What the ground's first bounce adds to the isotropic scattering sigma_s at
// a point for a view whose ground_excess() is ex: sum of sigma_i (k_i - 1).
vec3 ground_scattering(Scatter sc, vec4 ex)
{
	vec3 r = vec3(0.0);
	if (!GROUND_BLACK)
		for (int i = 0; i < N_CONST; i++)
			r += sc.s[i] * ex[i];
	return r;
}

// The scattering of the constituent that sees the lobe (ms_source). A
// Rayleigh lobe (g1 = 0) is the field's band 2 alone, which every phase
// sees by its own g2: sum sigma_i g2_i over the lobe's g2 (at Earth's ground
// the Mie layer, g2 0.71, sees it as much as the air, 0.1, in blue and five
// times as much in red).
vec3 forward_scattering(Scatter sc)
{
	if (MOMENT_CONST < 0)
		return vec3(0.0);
	if (P.c[max(MOMENT_CONST, 0)].PHASE_G1 != 0.0)
		return sc.s[max(MOMENT_CONST, 0)];
	vec3 f = vec3(0.0);
	for (int i = 0; i < N_CONST; i++)
		f += sc.s[i] * P.c[i].PHASE_G2;
	return f / P.c[max(MOMENT_CONST, 0)].PHASE_G2;
}

// multiscatter_at and the shape of the same texels (MomentTex).
vec4 multiscatter_shape_at(TAlt a, float mu_s, out vec4 ret_shape)
{
	MsTaps t = ms_taps(a, mu_s);
	ret_shape = ms_read(MomentTex, t);
	return ms_read_table(t);
}

// The higher orders at a point for one light: Hillaire's isotropic psi_ms
// scattered by sigma_s, the ground's first bounce (the share A of psi_ms)
// by sigma_s + ground (ground_scattering()). With a lobe constituent
// (MOMENT_CONST, forward its sigma_s) the multiply scattered light is not
// taken isotropic: multiscatter.comp describes it by the sun's aureole, a
// share a of a Henyey-Greenstein lobe of parameter g1 about the sunlight's
// direction, and its spherical harmonics b1 (band 1) and b2 (band 2).
// By Funk-Hecke a phase of Legendre moments g1, g2 scatters the bands
// toward the eye, o, as g1 b1(o) + g2 b2(o); two Henyey-Greenstein lobes
// convolve into one of parameter g1 g1 (their moments multiply), seen at
// o . sunlight = view . light. A forward phase (Mars' dust, g = 0.85) sees
// a field brightest near the horizon and around the sun, which the
// isotropic assumption reads far too dark. view_up: the view's cosine
// with the local vertical; ph: the light's (ray_phases), its cosine with
// the view and the lobe seen there.
vec3 ms_source(TAlt a, float mu_l, vec3 sigma_s, vec3 ground, vec3 forward, float view_up, Phases ph)
{
	float view_light = ph.mu;
	if (MOMENT_CONST < 0) {
		vec4 ms = multiscatter_at(a, mu_l);
		return (sigma_s + ms.a * ground) * ms.rgb;
	}
	// 3 m_z, 5 <P2(w_z)>, z, a with z = 3.75 (T_xx - T_yy) less the
	// aureole's under delta-M, 15 T_xz without (multiscatter.comp).
	vec4 sh;
	vec4 ms = multiscatter_shape_at(a, mu_l, sh);
	// o = -view in the frame of the light's vertical plane: along the
	// light's horizontal direction (undefined with the light at the
	// zenith, where the field has no such part by symmetry), and up.
	float s2 = 1.0 - mu_l * mu_l;
	float o_x = clamp((view_up * mu_l - view_light) * inversesqrt(max(s2, 1e-12)), -1.0, 1.0), o_z = -view_up;
	float b1 = sh.x * o_z;
	// o_x^2 - o_y^2 = 2 o_x^2 + o_z^2 - 1.
	float b2 = sh.y * (1.5 * o_z * o_z - 0.5) +
		   sh.z * (DELTA_CONST >= 0 ? 2.0 * o_x * o_x + o_z * o_z - 1.0 : o_x * o_z);
	vec2 g = ms_lobe_moments();
	// A truncated expansion may go negative where the field is strongly
	// directed; the light scattered never does.
	float lobe = sh.w * ph.ms_lobe;	// a (4 pi HG - 1)
	return max(sigma_s + ms.a * ground + forward * (g.x * b1 + g.y * b2 + lobe), vec3(0.0)) * ms.rgb;
}

// The light the cloud layers scatter into the air at the march's step
// for the light being added, from its layers' terms there (cloud_down,
// cloud_up: clouds.glsl's cloud_diffuse_at, which the march calls before
// each light's march_source; sky-view and aerial, where CLOUD_LAYERS > 0).
vec3 cloud_down = vec3(0.0), cloud_up = vec3(0.0);
vec3 cloud_diffuse_source(float mu_l, vec3 t_l, vec3 sigma_s, vec3 ground);

// In-scattered radiance source at a point for one light whose visible
// fraction is known (light_visible, or disk_visible_mean over a march
// step): single scattering through each constituent's phase plus the
// higher orders (ms_source).
vec3 light_source_lit(TAlt a, float mu_l, float visible, vec3 illum, vec3 phased, vec3 sigma_s, vec3 ground,
		      vec3 forward, float view_up, Phases ph)
{
	vec3 t_l = transmittance_lookup(a, mu_l);
	vec3 s = visible > 0.0 ? phased * (visible * t_l) : vec3(0.0);
	if (MULTISCATTER_ON) {
		vec3 ms = ms_source(a, mu_l, sigma_s, ground, forward, view_up, ph);
		if (CLOUD_LAYERS > 0)
			ms = ms * cloud_ms_open + cloud_diffuse_source(mu_l, t_l, sigma_s, ground);
		s += ms;
	}
	return s * illum;
}

// The part of a ray from the observer (altitude h0, direction dir in ENU)
// inside the shell and above the ground, from distance t0 for len, and the
// point where it starts: marches go from there, so that an observer far out
// in space (h0 = 1e6 km: r^2 ~ 1e12 km^2, an ulp of 6e4) does not cancel
// r^2 mu^2 against r^2 - rt^2 at every step. False if the ray misses.
struct Entry {
	float t0, len;
	float h, mu;	// altitude and cos-zenith of the ray where it starts
	float ez;	// the start's coordinate along the observer's vertical, from the centre
};

bool ray_in_shell(float h0, vec3 dir, out Entry en)
{
	float rb = P.BOTTOM_RADIUS_KM, shell = P.SHELL_KM, mu = dir.z;
	float r = rb + h0;
	en.t0 = 0.0;
	en.len = 0.0;
	en.h = max(h0, 0.0);
	en.mu = mu;
	en.ez = r;
	float tg;
	if (h0 <= shell) {
		en.len = hits_ground(en.h, mu, tg) ? tg : distance_to_top(en.h, mu);
		return en.len > 0.0;
	}
	// From space: enter the top sphere, if the ray reaches it. With the
	// ray's sine from dir.xy, rt^2 - (r sin)^2 factors without cancelling.
	float rt = rb + shell, sin_z = length(dir.xy);
	float disc = (rt - r * sin_z) * (rt + r * sin_z);
	if (mu >= 0.0 || disc <= 0.0)
		return false;
	// t0 = -r mu - sq cancels where the ray enters close by; the product of
	// the two roots is r^2 - rt^2, which has no cancellation.
	float sq = sqrt(disc);
	en.t0 = (h0 - shell) * (2.0 * rb + h0 + shell) / (-r * mu + sq);
	en.h = shell;
	en.mu = -sq / rt;
	en.ez = r * sin_z * sin_z - mu * sq;	// r + mu t0
	en.len = hits_ground(shell, en.mu, tg) ? tg : 2.0 * sq;
	return en.len > 0.0;
}

// ---- Delta-M for the higher orders (DELTA_CONST) ----
//
// Wiscombe's delta-M (1977) with a single-scattering correction after
// Nakajima and Tanaka (1988). The constituent's phase p is split into a
// forward peak of weight f, taken as no scattering at all, and the rest,
// (1 - f) p' with p' a Henyey-Greenstein phase of g' = (g1 - f) / (1 - f)
// (phase_delta_truncation). The scaled medium scatters sigma_s' = sigma_s -
// f sigma_D and has extinction sigma_t' = sigma_t - f sigma_D (sigma_D the
// constituent's scattering); its multiply scattered light is far less
// forward-peaked than the real one, which is what psi_ms's isotropic
// assumption needs. Which transmittance each part takes, so that every
// path is counted once:
// - single scattering is exact: the real phase p, the real transmittances
//   from the light to the point (T_l, the table) and from the point to the
//   eye (T_v, the march's tr);
// - the higher orders are the scaled medium's: multiscatter.comp computes
//   L2 and f_ms in it (the sunlight reaching each point through T_l' =
//   exp(-sum_k ext'_k L_k), the column densities L_k of the transmittance
//   texels; first scattering through p'; the walls between points through
//   sigma_t'), and the march scatters the resulting psi' with sigma_s'
//   through T_v' (the march's second product, over sigma_t'): light that
//   the peak scatters on the way to the eye stays on its way;
// - the paths in which the peak scattered the light one or more times,
//   toward the point or on to the eye, besides one last deflection toward
//   the eye: T_l' T_v' - T_l T_v of them (the exact single scattering has
//   those with no peak scattering), so the march adds that difference
//   scattered by the other constituents' phases and by DELTA_CONST's
//   widened one (delta_peak_phase()). Nakajima and Tanaka's TMS drops the
//   difference, which leaves Mars' day sky far too dark.
// f is the phase's 6th Legendre moment, not delta-Eddington's 2nd: a wide
// peak taken as undeflected brightens the horizon, where the light changes
// within the peak's width. docs/physics.md derives the split; the figures
// are in docs/findings/shaders.md.

// The scattering that the scaled medium removes, per unit density of
// DELTA_CONST: f sigma_D.
vec3 delta_removed()
{
	int k = max(DELTA_CONST, 0);
	return DELTA_CONST >= 0 ? P.c[k].DELTA_F * P.c[k].scattering.rgb : vec3(0.0);
}

// The column densities of every constituent from the altitude of a toward
// mu to the top, bilinear at the transmittance lookup's taps: the scaled
// medium's transmittance is exp(-(ext' * columns)), one lookup as the
// table's (the multi-scattering pass reads no other).
vec4 columns_at(TAlt a, float mu)
{
	return bilinear(ColumnTex, T_W, transmittance_x(a, mu), a.t_rows);
}

// What the delta-M scaled medium has at a march step (delta_source's
// arguments): the scattering it removes, its scattering, ground term and
// lobe constituent's scattering (for the shape of the field, ms_source);
// the peak's optical depth from the eye to the middle of the step
// (delta_peak_phase()), which tau_view carries along the march, dt the
// step's length; zero without delta-M.
struct Scaled {
	vec3 removed, sigma_s, ground, forward;
	float tau_view;
};

Scaled scaled_step(Scatter sc, Medium m, float view_up, float dt, inout float tau_view)
{
	Scaled d = Scaled(vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), 0.0);
	if (DELTA_CONST < 0)
		return d;
	int k = max(DELTA_CONST, 0);
	d.removed = sc.s[k] * P.c[k].DELTA_F;
	Scatter scs = sc;
	scs.s[k] -= d.removed;
	d.sigma_s = m.scattering - d.removed;
	d.ground = ground_scattering(scs, ground_excess(view_up));
	d.forward = scs.s[k];
	float dtau = dot(d.removed, vec3(1.0 / 3.0)) * dt;
	d.tau_view = tau_view + 0.5 * dtau;
	tau_view += dtau;
	return d;
}

// The last deflection of the light that the peak scattered n >= 1 times
// besides (phase_delta_peak_phase). It is the whole phase p, the peak's own
// share included: with only (1 - f) p' here, light that only the peak ever
// scattered would leave the sky. The n peak
// scatterings widen it: the constituent's phase at g h^n (exact for
// Henyey-Greenstein, whose moments multiply; h the peak's own, from its
// 6th moment), with n the mean count given one or more, tau / (1 -
// exp(-tau)), for the peak's optical depth tau toward the light and back
// to the eye (delta_source). The widened beam reaches the point only from
// above its horizon: the share of it above the local horizontal, a
// logistic of the light's elevation over the spread sigma sqrt(n), keeps a
// low sun from brightening the horizon band.
float delta_peak_phase(float mu_l, float tau, Phases ph)
{
	int k = max(DELTA_CONST, 0);
	float n = tau < 1e-4 ? 1.0 + 0.5 * tau : tau / (1.0 - exp(-tau));
	float above = 1.0 / (1.0 + exp(-1.702 * asin(clamp(mu_l, -1.0, 1.0)) / max(P.DELTA_PEAK_SPREAD_RAD * sqrt(n), 1e-6)));
	return above * phase(phase_kind(k), P.c[k].PHASE_G * pow(P.DELTA_PEAK_H, n), ph.mu);
}

// The march's source for one light with delta-M: ret_real weighs with the
// real transmittance along the view (tr), ret_scaled with the scaled one.
// phased: the real phase-weighted scattering, sc and ph its parts;
// ds: the scaled medium at the step (scaled_step()).
void delta_source(TAlt a, float mu_l, float visible, vec3 illum, Scatter sc, Phases ph, vec3 phased, Scaled ds,
		  float view_up, out vec3 ret_real, out vec3 ret_scaled)
{
	int k = max(DELTA_CONST, 0);
	vec3 t_l = transmittance_lookup(a, mu_l);
	vec3 t = visible > 0.0 ? visible * t_l : vec3(0.0);
	// The peak's optical depth toward the light, f sigma_D L_D (L_D
	// DELTA_CONST's column density): T_l' / T_l = exp of it.
	vec3 depth = delta_removed() * columns_at(a, mu_l)[k];
	float tau = ds.tau_view + dot(depth, vec3(1.0 / 3.0));
	vec3 phased_s = phased + sc.s[k] * (delta_peak_phase(mu_l, tau, ph) - ph.p[k]);
	ret_real = (phased - phased_s) * t * illum;
	ret_scaled = phased_s * t * exp(min(depth, vec3(80.0)));
	if (MULTISCATTER_ON) {
		vec3 ms = ms_source(a, mu_l, ds.sigma_s, ds.ground, ds.forward, view_up, ph);
		if (CLOUD_LAYERS > 0)
			ms = ms * cloud_ms_open + cloud_diffuse_source(mu_l, t_l, ds.sigma_s, ds.ground);
		ret_scaled += ms;
	}
	ret_scaled *= illum;
}


// The sky-view and aerial marches' source for one light, added to real
// (weighed by the view's transmittance) and, with delta-M, to scaled (by the
// scaled one): light_source_lit, or delta_source where DELTA_CONST is set.
// With cloud layers, cloud_down and cloud_up hold this light's layer terms
// at the step (cloud_diffuse_at).
void march_source(TAlt a, float mu_l, float visible, vec3 illum, Scatter sc, Phases ph, Medium m, vec3 ground,
		  vec3 forward, Scaled ds, float view_up, inout vec3 real, inout vec3 scaled)
{
	vec3 p = phased(sc, ph);
	if (DELTA_CONST >= 0) {
		vec3 r, rs;
		delta_source(a, mu_l, visible, illum, sc, ph, p, ds, view_up, r, rs);
		real += r;
		scaled += rs;
	} else {
		real += light_source_lit(a, mu_l, visible, illum, p, m.scattering, ground, forward, view_up, ph);
	}
}
