/* present.comp.glsl — the picture on the GPU: exposure × radiance → ACES fit → sRGB (the formulas of
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

void main() {
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= u_size.x || px.y >= u_size.y) return;
  vec3 c = radiance[px.y * u_size.x + px.x].rgb * u_exposure;
  /* non-finite radiance shows black, as on the CPU (which also counts it) */
  if (any(isnan(c)) || any(isinf(c))) c = vec3(0.0);
  c = ocg_srgb_encode3(ocg_aces_fit(c));
  if (px.x < u_overlay_size.x && px.y < u_overlay_size.y) {
    vec4 o = texelFetch(u_overlay, px, 0);
    c = o.rgb + c * (1.0 - o.a);
  }
  imageStore(u_out, px, vec4(c, 1.0));
}
