/* reproject.comp.glsl — fills a frame of which one pixel in each 4×4 block was traced (the phase)
 * from the previous frame: each other pixel's ray, at the depth its pixel had last frame, is
 * projected into the previous camera and the history there is taken if its depth agrees with that
 * point's; otherwise the block's freshly traced pixel stands in (client/gl/ocv_gl.h, "Reprojection").
 * Positions are relative to the current eye; the previous eye's offset comes in from double on the
 * CPU, so planet-scale coordinates never reach float. */
layout(local_size_x = 8, local_size_y = 8) in;

layout(std430, binding = 0) readonly buffer Cur { vec4 cur[]; };          /* this frame: traced pixels only */
layout(std430, binding = 1) readonly buffer CurDepth { float cur_depth[]; };
layout(std430, binding = 2) readonly buffer Hist { vec4 hist[]; };        /* the previous frame */
layout(std430, binding = 3) readonly buffer HistDepth { float hist_depth[]; };
layout(std430, binding = 4) writeonly buffer Out { vec4 out_color[]; };   /* this frame, the next history */
layout(std430, binding = 5) writeonly buffer OutDepth { float out_depth[]; };
layout(std430, binding = 6) buffer Stats { uint stats[2]; };
layout(std430, binding = 7) readonly buffer HistCount { uint hist_count[]; }; /* samples averaged so far */
layout(std430, binding = 8) writeonly buffer OutCount { uint out_count[]; };              /* reprojected, filled from the block */

layout(location = 0) uniform ivec2 u_size;
layout(location = 1) uniform int u_phase;
layout(location = 2) uniform int u_have_hist;
layout(location = 3) uniform vec3 u_fwd;
layout(location = 4) uniform vec3 u_right;
layout(location = 5) uniform vec3 u_up;
layout(location = 6) uniform vec2 u_tan;
layout(location = 7) uniform vec3 u_pfwd;  /* the previous camera */
layout(location = 8) uniform vec3 u_pright;
layout(location = 9) uniform vec3 u_pup;
layout(location = 10) uniform vec2 u_ptan;
layout(location = 11) uniform vec3 u_peye; /* previous eye − current eye, m */
layout(location = 12) uniform float u_alpha; /* < 1: the traced pixel blends into its history (jitter
                                                averages out, Ford's temporal accumulation) */
layout(location = 13) uniform int u_moved;   /* the camera moved since the history was made */
layout(location = 14) uniform int u_refresh; /* the state changed since the history was made: history is
                                                clamped to what is traced around it now... */
layout(location = 15) uniform uint u_fresh;  /* ...unless its block position (bit x | y<<2) was traced
                                                since the change */

/* The history pixel this pixel's ray came from last frame, or -1 (off screen, behind, or its depth
 * disagrees with the reprojected point's). */
int ocv_history_at(ivec2 px, float d) {
  float x = (2.0 * (float(px.x) + 0.5) / float(u_size.x) - 1.0) * u_tan.x;
  float y = (1.0 - 2.0 * (float(px.y) + 0.5) / float(u_size.y)) * u_tan.y;
  vec3 dir = normalize(u_fwd + u_right * x + u_up * y);
  vec3 q = dir * d - u_peye; /* the point seen from the previous eye */
  float z = dot(q, u_pfwd);
  if (z <= 0.0) return -1;
  float sx = dot(q, u_pright) / (z * u_ptan.x), sy = dot(q, u_pup) / (z * u_ptan.y);
  vec2 h = vec2((sx + 1.0) * 0.5 * float(u_size.x) - 0.5, (1.0 - sy) * 0.5 * float(u_size.y) - 0.5);
  ivec2 j = ivec2(floor(h + 0.5));
  if (any(lessThan(j, ivec2(0))) || any(greaterThanEqual(j, u_size))) return -1;
  int ji = j.y * u_size.x + j.x;
  float dq = length(q);
  return abs(hist_depth[ji] - dq) <= 0.02 * dq + 1.0 ? ji : -1;
}

/* This pixel's ray at the depth it had last frame. */
int ocv_history_of(ivec2 px, int i) { return ocv_history_at(px, hist_depth[i]); }

/* A nearer surface beside this pixel last frame (3×3) that this pixel's ray now meets where the
 * history saw it: the surface moved over the pixel (parallax), so its far history is stale. */
bool ocv_covered(ivec2 px, float d) {
  float near = d;
  for (int y = -1; y <= 1; y++)
    for (int x = -1; x <= 1; x++) {
      ivec2 n = clamp(px + ivec2(x, y), ivec2(0), u_size - 1);
      near = min(near, hist_depth[n.y * u_size.x + n.x]);
    }
  return near < d * 0.98 - 1.0 && ocv_history_at(px, near) >= 0;
}

/* The traced pixels of the 3×3 blocks around px bound what its history may hold (neighbourhood
 * clamping: stale history cannot drift outside what is seen now). */
void ocv_neighbourhood(ivec2 px, out vec4 lo, out vec4 hi) {
  lo = vec4(1e30);
  hi = vec4(-1e30);
  for (int by = -1; by <= 1; by++)
    for (int bx = -1; bx <= 1; bx++) {
      ivec2 b = (px & ~3) + ivec2(bx, by) * 4 + ivec2(u_phase & 3, u_phase >> 2);
      if (any(lessThan(b, ivec2(0))) || any(greaterThanEqual(b, u_size))) continue;
      vec4 c = cur[b.y * u_size.x + b.x];
      lo = min(lo, c);
      hi = max(hi, c);
    }
}

/* Where the camera moved, history is also stale when it saw farther than every pixel traced this
 * frame around this one (the 2×2 traced pixels that bracket it): a cloud moved over what the
 * history saw as far, and a far depth reprojects onto far history and passes ocv_history_of. A still
 * camera's history is exact and is kept (a thin feature between traced pixels would be lost). */
bool ocv_behind_fresh(ivec2 px, float d) {
  ivec2 t = (px & ~3) + ivec2(u_phase & 3, u_phase >> 2); /* this block's traced pixel */
  ivec2 side = ivec2(px.x >= t.x ? 4 : -4, px.y >= t.y ? 4 : -4);
  float hi = -1e30;
  for (int k = 0; k < 4; k++) {
    ivec2 b = t + ivec2(k & 1, k >> 1) * side;
    if (any(lessThan(b, ivec2(0))) || any(greaterThanEqual(b, u_size))) continue;
    hi = max(hi, cur_depth[b.y * u_size.x + b.x]);
  }
  return d > hi * 1.02 + 1.0;
}

void main() {
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= u_size.x || px.y >= u_size.y) return;
  int i = px.y * u_size.x + px.x;
  if (((px.x & 3) | ((px.y & 3) << 2)) == u_phase) { /* traced this frame */
    vec4 c = cur[i];
    uint n = 1u;
    if (u_have_hist != 0 && u_alpha < 1.0) {
      int ji = ocv_history_of(px, i);
      if (ji >= 0 && hist_count[ji] > 0u) { /* a history of this pixel's own samples, not a block fill */
        vec4 lo, hi;
        ocv_neighbourhood(px, lo, hi);
        n = hist_count[ji] + 1u;
        c = mix(clamp(hist[ji], lo, hi), c, max(u_alpha, 1.0 / float(n))); /* a running mean, then an EMA */
      }
    }
    out_color[i] = c;
    out_depth[i] = cur_depth[i];
    out_count[i] = min(n, 1000u);
    return;
  }
  ivec2 b = min((px & ~3) + ivec2(u_phase & 3, u_phase >> 2), u_size - 1);
  int bi = b.y * u_size.x + b.x;
  if (u_have_hist != 0) {
    int ji = ocv_history_of(px, i);
    if (ji >= 0 && u_moved != 0 && (ocv_behind_fresh(px, hist_depth[ji]) || ocv_covered(px, hist_depth[ji]))) ji = -1;
    if (ji >= 0) {
      vec4 c = hist[ji];
      uint pos = uint((ji % u_size.x) & 3) | (uint((ji / u_size.x) & 3) << 2);
      if (u_refresh != 0 && ((u_fresh >> pos) & 1u) == 0u) {
        /* a new state: what changed shows at once, detail the history holds stays */
        vec4 lo, hi;
        ocv_neighbourhood(px, lo, hi);
        c = clamp(c, lo, hi);
      }
      out_color[i] = c;
      out_depth[i] = hist_depth[i];
      out_count[i] = hist_count[ji];
      atomicAdd(stats[0], 1u);
      return;
    }
  }
  atomicAdd(stats[1], 1u);
  out_color[i] = cur[bi];
  out_depth[i] = cur_depth[bi];
  out_count[i] = 0u; /* not a sample of this pixel */
}
