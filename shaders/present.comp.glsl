/* present.comp.glsl — the picture on the GPU: radiance (upsampled when the frame was traced at a lower
 * resolution) × exposure → ACES fit → sRGB (the formulas of
 * shaders/optics.h, which oc_image_tonemap() runs on the CPU), then a premultiplied RGBA8 overlay
 * (the HUD, client/hud.h) composited over it, into an RGBA8 image the window draws. The frame never
 * leaves the GPU (client/gl/gl_present.c). */
layout(local_size_x = 8, local_size_y = 8) in;

layout(std430, binding = 0) readonly buffer Radiance { vec4 radiance[]; }; /* w×h, rows from the top */
layout(rgba8, binding = 0) writeonly uniform image2D u_out;                 /* rows from the top */
layout(binding = 1) uniform sampler2D u_overlay;                            /* premultiplied; rows from the top */

layout(location = 0) uniform ivec2 u_size;
layout(location = 1) uniform float u_exposure;
layout(location = 2) uniform ivec2 u_overlay_size; /* (0, 0): none */
layout(location = 3) uniform ivec2 u_src_size;     /* the radiance buffer's size (a frame traced smaller) */

vec3 ocv_radiance(ivec2 q) {
  q = clamp(q, ivec2(0), u_src_size - 1);
  return radiance[q.y * u_src_size.x + q.x].rgb;
}

/* The radiance at output pixel px: the buffer's pixel when it has the picture's size, else bilinear
 * between the 4 source pixels around px's centre (texel centres aligned, edges clamped). */
vec3 ocv_source(ivec2 px) {
  if (u_src_size == u_size) return radiance[px.y * u_size.x + px.x].rgb;
  vec2 u = (vec2(px) + 0.5) * vec2(u_src_size) / vec2(u_size) - 0.5;
  vec2 f = u - floor(u);
  ivec2 q = ivec2(floor(u));
  vec3 a = mix(ocv_radiance(q), ocv_radiance(q + ivec2(1, 0)), f.x);
  vec3 b = mix(ocv_radiance(q + ivec2(0, 1)), ocv_radiance(q + ivec2(1, 1)), f.x);
  return mix(a, b, f.y);
}

void main() {
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= u_size.x || px.y >= u_size.y) return;
  vec3 c = ocv_source(px) * u_exposure;
  /* non-finite radiance shows black, as on the CPU (which also counts it) */
  if (any(isnan(c)) || any(isinf(c))) c = vec3(0.0);
  c = ocg_srgb_encode3(ocg_aces_fit(c));
  if (px.x < u_overlay_size.x && px.y < u_overlay_size.y) {
    vec4 o = texelFetch(u_overlay, px, 0);
    c = o.rgb + c * (1.0 - o.a);
  }
  imageStore(u_out, px, vec4(c, 1.0));
}
