// columns.comp - column densities per transmittance texel: the integral of
// each constituent's density profile along the texel's ray to the top of the
// atmosphere, geometry and profiles only (an internal buffer, not published).
//
// Optical depth is linear in the coefficients, tau = sum_k ext_k L_k, so
// transmittance.glsl weighs these columns by the extinctions: this pass
// writes the transmittance of its texels too, and a change of coefficients
// alone (the weather) runs transmittance.comp from the kept columns
// instead. Mirrors optical_depth() and column_linear() in truth/model.c.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "transmittance.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// A straight ray seen from the planet's centre: impact parameter p (the
// radius of the tangent point) and the tangent point's altitude, kept apart
// because p - rb would cancel. Along the ray u = t + r mu, and the altitude
// is h(u) = h_tan + u^2 / (s + p), s = sqrt(u^2 + p^2).
struct Chord {
	float p, h_tan;
};

float chord_altitude(Chord c, float u)
{
	float sp = sqrt(u * u + c.p * c.p) + c.p;
	return sp > 0.0 ? c.h_tan + u * u / sp : c.h_tan;
}

// |u| where the chord crosses altitude h (>= h_tan).
float chord_crossing(Chord c, float h)
{
	return safe_sqrt((h - c.h_tan) * (h + c.h_tan + 2.0 * P.BOTTOM_RADIUS_KM));
}

// x - asinh(x) for x >= 0 without cancellation: the series below 0.5 (its
// first left-out term is 1e-6 of the sum there, float32's asinh is as good
// above). Earth's rays stay below 0.18.
float x_minus_asinh(float x)
{
	if (x >= 0.5)
		return x - asinh(x);
	float x2 = x * x;
	return x * x2 * (1.0 / 6.0 - x2 * (3.0 / 40.0 - x2 * (5.0 / 112.0 - x2 * (35.0 / 1152.0 -
	       x2 * (63.0 / 2816.0 - x2 * (231.0 / 13312.0 - x2 * (143.0 / 10240.0 -
	       x2 * (6435.0 / 557056.0))))))));
}

// The integral of h(u) over [ua, ub] (0 <= ua <= ub) minus its trapezoid:
// -p^2 (sinh(dtheta) - dtheta) / 2 with u = p sinh(theta); sinh(dtheta) is
// written without p in a denominator (p = 0 on a vertical ray).
float chord_curvature(Chord c, float ua, float ub)
{
	float sa = sqrt(ua * ua + c.p * c.p), sb = sqrt(ub * ub + c.p * c.p);
	float den = ub * sa + ua * sb;
	if (!(c.p > 0.0) || !(den > 0.0))
		return 0.0;
	return -0.5 * c.p * c.p * x_minus_asinh((ub - ua) * (ub + ua) / den);
}

const int N_KINKS = 5;

// A profile of clamped linear layers: l0, l1 (exp_term, exp_scale,
// linear, constant), layer 0 below w.
struct Linear {
	vec4 l0, l1;
	float w;
};

// Over [ua, ub], where the profile is linear between the altitudes ha and
// hb: the trapezoid of the end densities (no cancellation) plus the slope
// times the chord's curvature.
float column_piece(Linear f, Chord c, float ua, float ha, float ub, float hb)
{
	float hm = 0.5 * (ha + hb);
	vec4 l = hm < f.w ? f.l0 : f.l1;
	float dm = l.z * hm + l.w;
	if (dm <= 0.0)
		return 0.0;
	if (dm >= 1.0)
		return ub - ua;
	float da = clamp(l.z * ha + l.w, 0.0, 1.0), db = clamp(l.z * hb + l.w, 0.0, 1.0);
	return max((ub - ua) * 0.5 * (da + db) + l.z * chord_curvature(c, ua, ub), 0.0);
}

// Over |u| in [lo, hi], 0 <= lo, where the altitude rises with |u|: cut at
// every kink crossed, the next one the lowest kink above the last. Kinks are
// not sorted: an insertion sort of a local array came out of lavapipe with
// one element lost and another doubled.
float column_rising(Linear f, Chord c, float kinks[N_KINKS], float lo, float hi)
{
	float ua = lo, ha = chord_altitude(c, lo), h_hi = chord_altitude(c, hi), sum = 0.0;
	for (int i = 0; i < N_KINKS; i++) {
		float next = h_hi;
		for (int j = 0; j < N_KINKS; j++)
			if (kinks[j] > ha && kinks[j] < next)
				next = kinks[j];
		if (!(next < h_hi))
			break;
		float ub = clamp(chord_crossing(c, next), ua, hi);
		sum += column_piece(f, c, ua, ha, ub, next);
		ua = ub;
		ha = next;
	}
	return sum + column_piece(f, c, ua, ha, hi, h_hi);
}

// The column of a profile of clamped linear layers (ozone's tent) from u0
// to u1 along the chord, in closed form: steps that take the altitude as
// linear in t miss its curvature near a grazing ray's tangent point. The
// ray descends to the tangent point (u < 0), then rises.
float column_linear(Linear f, Chord c, float u0, float u1)
{
	// Kinks: the layer boundary and where a layer's linear term meets the
	// clamps; one a layer never reaches only cuts a piece in two, and a
	// flat layer repeats the boundary.
	float kinks[N_KINKS];
	kinks[0] = f.w;
	kinks[1] = f.l0.z != 0.0 ? -f.l0.w / f.l0.z : f.w;
	kinks[2] = f.l0.z != 0.0 ? (1.0 - f.l0.w) / f.l0.z : f.w;
	kinks[3] = f.l1.z != 0.0 ? -f.l1.w / f.l1.z : f.w;
	kinks[4] = f.l1.z != 0.0 ? (1.0 - f.l1.w) / f.l1.z : f.w;
	float sum = 0.0;
	if (u0 < 0.0)
		sum += column_rising(f, c, kinks, max(-u1, 0.0), -u0);
	if (u1 > 0.0)
		sum += column_rising(f, c, kinks, max(u0, 0.0), u1);
	return sum;
}

// Whether constituent k's layer (0 or 1) has an exponential term: the
// column pass's EXP_MASK also says which (eng_column_spec).
bool exp_in_layer(int k, int layer)
{
	return (EXP_MASK & (1 << (4 + 4 * layer + k))) != 0;
}

// Mean of exp(k h) over [ha, hb], exact when the altitude changes linearly
// over the step, given ea = exp(k ha) and eb = exp(k hb). A difference of
// two exponentials of real altitudes, never exp(k hm) sinh(x) / x, which is
// 0 * inf = NaN for a 0.1 km scale height over a 100 km step; the series
// keeps the short-step limit exact.
float mean_exp(float k, float ha, float hb, float ea, float eb)
{
	float x = 0.5 * k * (hb - ha);
	if (abs(x) < 0.1)
		return exp(0.5 * k * (ha + hb)) * (1.0 + x * x * (1.0 / 6.0 + x * x / 120.0));
	return (eb - ea) / (2.0 * x);
}

void main()
{
	load_params();
	ivec2 px = ivec2(gl_GlobalInvocationID.xy);
	if (px.x >= OUT_W || px.y >= OUT_H)
		return;
	// Rays from low altitudes cross more of the profiles' kinks.
	px.y = interleaved_row(px.y, OUT_H);

	float rb = P.BOTTOM_RADIUS_KM, shell = P.SHELL_KM;
	float H = P.TOP_DISTANCE_KM;
	float x_mu = tex_to_unit((float(px.x) + 0.5) / float(OUT_W), OUT_W);
	float x_r = tex_to_unit((float(px.y) + 0.5) / float(OUT_H), OUT_H);
	float rho = H * x_r;
	float r = sqrt(rho * rho + rb * rb);
	float h = rho * rho / (r + rb);
	float d_min = shell - h, d_max = rho + H;
	float d = d_min + x_mu * (d_max - d_min);
	float mu = d <= 0.0 ? 1.0 : clamp((H * H - rho * rho - d * d) / (2.0 * r * d), -1.0, 1.0);
	// At the top row h rounds above the shell and d_min below 0: a negative
	// length would make exp(-tau) > 1.
	d = max(d, 0.0);

	// Profiles with an exponential term: each step integrates every layer
	// exactly for a linear change of altitude (mean_exp): a midpoint rule
	// at 2.5 km steps reads a thin layer's column short.
	// Loop invariants by hand: lavapipe's LLVM passes do not hoist them.
	float column[4];
	vec4 lay0[4], lay1[4];
	float width[4];
	for (int k = 0; k < N_CONST; k++) {
		Constituent c = P.c[k];
		lay0[k] = vec4(c.layer0.yzw, c.LAYER0_CONSTANT);
		lay1[k] = vec4(c.layer0c_1.yzw, c.LAYER1_CONSTANT);
		width[k] = c.LAYER0_WIDTH_KM;
		column[k] = 0.0;
	}
	if ((EXP_MASK & 15) != 0) {
		float dt = d / float(STEPS);
		float excess0 = rho2(h), two_r_mu = 2.0 * r * mu, rb2 = rb * rb;
		float ha = h;
		// exp(k h) of each exponential layer at the step's start: the
		// previous step's end, the same bits, so a step takes one exp()
		// per such layer and the midpoint's, not three.
		vec4 ea0 = vec4(0.0), ea1 = vec4(0.0);
		for (int k = 0; k < N_CONST; k++) {
			if (exp_in_layer(k, 0))
				ea0[k] = exp(lay0[k].y * h);
			if (exp_in_layer(k, 1))
				ea1[k] = exp(lay1[k].y * h);
		}
		// do-while: lavapipe ends a for loop with one more step, every
		// lane off (STEPS >= 1).
		int i = 0;
		do {
			float t = float(i + 1) * dt;
			float excess = excess0 + t * (t + two_r_mu);
			float hb = excess / (sqrt(rb2 + max(excess, 0.0)) + rb);
			float hm = 0.5 * (ha + hb);
			for (int k = 0; k < N_CONST; k++) {
				if ((EXP_MASK & (1 << k)) == 0)
					continue;
				bool lower = hm < width[k];
				vec4 l = lower ? lay0[k] : lay1[k];
				float eb0 = exp_in_layer(k, 0) ? exp(lay0[k].y * hb) : 0.0;
				float eb1 = exp_in_layer(k, 1) ? exp(lay1[k].y * hb) : 0.0;
				float e = l.x != 0.0 ? l.x * mean_exp(l.y, ha, hb, lower ? ea0[k] : ea1[k],
								      lower ? eb0 : eb1) : 0.0;
				ea0[k] = eb0;
				ea1[k] = eb1;
				column[k] += clamp(e + l.z * hm + l.w, 0.0, 1.0);
			}
			ha = hb;
		} while (++i < STEPS);
		for (int k = 0; k < N_CONST; k++)
			if ((EXP_MASK & (1 << k)) != 0)
				column[k] *= dt;
	}

	// Profiles of linear layers in closed form, on the chord of the ray.
	float u0 = r * mu;
	float q = rho * rho - u0 * u0;	// p^2 - rb^2
	Chord ch;
	ch.p = safe_sqrt(rb * rb + q);
	ch.h_tan = q / (ch.p + rb);
	for (int k = 0; k < N_CONST; k++) {
		if ((EXP_MASK & (1 << k)) != 0)
			continue;
		Linear f;
		f.l0 = lay0[k];
		f.l1 = lay1[k];
		f.w = width[k];
		column[k] = column_linear(f, ch, u0, u0 + d);
	}
	vec4 out_column = vec4(0.0);
	for (int k = 0; k < N_CONST; k++)
		out_column[k] = column[k];
	CB.d[px.y * OUT_W + px.x] = out_column;
	// The column pass runs only with the transmittance table: the same
	// dispatch writes it, saving a dispatch and a barrier.
	store_transmittance(px.y * OUT_W + px.x, out_column);
}
