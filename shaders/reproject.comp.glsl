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
layout(std430, binding = 6) buffer Stats { uint stats[2]; };              /* reprojected, filled from the block */

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

void main() {
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= u_size.x || px.y >= u_size.y) return;
  int i = px.y * u_size.x + px.x;
  if (((px.x & 3) | ((px.y & 3) << 2)) == u_phase) { /* traced this frame */
    out_color[i] = cur[i];
    out_depth[i] = cur_depth[i];
    return;
  }
  ivec2 b = min((px & ~3) + ivec2(u_phase & 3, u_phase >> 2), u_size - 1);
  int bi = b.y * u_size.x + b.x;
  if (u_have_hist != 0) {
    float x = (2.0 * (float(px.x) + 0.5) / float(u_size.x) - 1.0) * u_tan.x;
    float y = (1.0 - 2.0 * (float(px.y) + 0.5) / float(u_size.y)) * u_tan.y;
    vec3 dir = normalize(u_fwd + u_right * x + u_up * y);
    float d = hist_depth[i];
    vec3 q = dir * d - u_peye; /* the point seen from the previous eye */
    float z = dot(q, u_pfwd);
    if (z > 0.0) {
      float sx = dot(q, u_pright) / (z * u_ptan.x), sy = dot(q, u_pup) / (z * u_ptan.y);
      vec2 h = vec2((sx + 1.0) * 0.5 * float(u_size.x) - 0.5, (1.0 - sy) * 0.5 * float(u_size.y) - 0.5);
      ivec2 j = ivec2(floor(h + 0.5));
      if (all(greaterThanEqual(j, ivec2(0))) && all(lessThan(j, u_size))) {
        int ji = j.y * u_size.x + j.x;
        float dq = length(q), dh = hist_depth[ji];
        if (abs(dh - dq) <= 0.02 * dq + 1.0) {
          out_color[i] = hist[ji];
          out_depth[i] = d;
          atomicAdd(stats[0], 1u);
          return;
        }
      }
    }
  }
  atomicAdd(stats[1], 1u);
  out_color[i] = cur[bi];
  out_depth[i] = cur_depth[bi];
}
