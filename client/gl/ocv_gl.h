/* ocv_gl.h — the viewer's GL renderer: headless context, GLSL programs from the shared headers,
 * GPU copy of a state, and the raymarch compute pass that reproduces the CPU reference renderer
 * (common/oc_render.c) on the GPU. See client/gl/README.md for the GPU data layout.
 *
 * Threads: every call that touches GL must be made on the thread that made the context current
 * (ocv_gl_context_init); ocv_gl_shader_dir(), ocv_gl_read_file() and the ocv_gl_src_* builders but
 * ocv_gl_src_compile() need no context. Errors: negative OC_E* codes with a one-line reason in `why`. */
#ifndef OC_CLIENT_GL_H
#define OC_CLIENT_GL_H

#include <epoxy/gl.h> /* GLuint; libepoxy, never <GL/gl.h> */
#include <stddef.h>
#include <stdint.h>

#include "oc_budget.h" /* oc_budget_t, OC_SLOT_BYTES, OC_RECORD_BYTES */
#include "oc_render.h" /* oc_render_desc_t, oc_image_t, oc_state_t */
#include "interp.h"    /* ocv_interp_t (client/) */

/* ---- Context (gl_context.c) ------------------------------------------------------------------------ */

typedef struct ocv_gl_context_s ocv_gl_context_t;

/*! ocv_gl_context_init() : a headless OpenGL 4.5 core context, current on this thread. EGL platforms
 *  tried in order: surfaceless Mesa (llvmpipe, no X server), each EGL device (NVIDIA), the default
 *  display. @return the context, or NULL with why naming each platform's failure. */
ocv_gl_context_t *ocv_gl_context_init(char *why, size_t why_len);
/*! ocv_gl_context_free() : releases the context (NULL is fine). The EGL display is not terminated:
 *  Mesa would dlclose its driver and leak-check tools could no longer name its allocations. */
void ocv_gl_context_free(ocv_gl_context_t *c);
/*! ocv_gl_context_platform() : which EGL platform worked ("EGL_PLATFORM_SURFACELESS_MESA", ...). */
const char *ocv_gl_context_platform(const ocv_gl_context_t *c);
/*! ocv_gl_context_describe() : "vendor | renderer | version | via platform" into out. */
void ocv_gl_context_describe(const ocv_gl_context_t *c, char *out, size_t cap);

/* ---- Programs (gl_program.c) ------------------------------------------------------------------------ */

/* GLSL has no #include: a program's source is the concatenation of named segments (the prelude, the
 * shared headers, the kernel). The first line of each segment in the concatenation is recorded and
 * every segment after the first is preceded by "#line <its first line>", so that drift inside one
 * segment (Mesa's glcpp joins a function-like macro call spanning lines onto one line) does not
 * spread to the next. The compiler's "0:LINE(COL)" (Mesa) or "0(LINE)" (NVIDIA) is then rewritten as
 * "SEGMENT:LINE(COL)"; the source-string number is ignored (Mesa 22.3 prints it inconsistently). */

#define OCV_GL_MAX_SEGMENTS 32

typedef struct {
  char *text;      /**< the concatenation, NUL-terminated, always ending with '\n' (NULL while empty) */
  size_t len, cap; /**< bytes in text (without the NUL) and allocated */
  int lines;       /**< lines in text so far, #line directives included */
  int nseg;
  struct {
    char name[256]; /**< as messages name it: "shaders/optics.h", "<kernel>" */
    int first;      /**< 1-based line of the segment's first line in text */
    int count;      /**< its lines */
  } seg[OCV_GL_MAX_SEGMENTS];
  int failed;    /**< an add failed: later adds are no-ops and ocv_gl_src_compile() reports why */
  char why[512]; /**< the first failure: "out of memory", "more than 32 source segments", "cannot read PATH" */
} ocv_gl_src_t;

/*! ocv_gl_src_init() : s starts with "#version 450\n#define OC_GLSL\n" (segment "<prelude>"), then
 *  `defines` (segment "<defines>") unless NULL. @return 0, or -1 with s->why (free s all the same). */
int ocv_gl_src_init(ocv_gl_src_t *s, const char *defines);
/*! ocv_gl_src_add() : appends a piece of source named `name` in messages; a missing final newline is
 *  supplied. @return 0, or -1 with s->why set (and s->failed, so later calls are no-ops). */
int ocv_gl_src_add(ocv_gl_src_t *s, const char *name, const char *text);
/*! ocv_gl_src_add_file() : appends the file at `path`, named `name` in messages (path itself if NULL).
 *  @return 0, or -1 with s->why ("cannot read PATH", ...) and s->failed set. */
int ocv_gl_src_add_file(ocv_gl_src_t *s, const char *name, const char *path);
/*! ocv_gl_src_free() : releases the text; s is left empty (initialise it again to reuse it). */
void ocv_gl_src_free(ocv_gl_src_t *s);
/*! ocv_gl_src_map_line() : the segment holding line `line` of the concatenation, and in *local the line
 *  within it. @return the segment's name, or NULL outside every segment (or on a #line directive). */
const char *ocv_gl_src_map_line(const ocv_gl_src_t *s, int line, int *local);
/*! ocv_gl_src_translate_log() : a GLSL info log with each "0:L(C): msg" (Mesa) or "0(L) : msg"
 *  (NVIDIA) rewritten as "name:l(C): msg" / "name:l : msg"; other lines copied unchanged, every line
 *  ending with '\n'. @return a malloc'd string (caller frees), or NULL when out of memory. */
char *ocv_gl_src_translate_log(const ocv_gl_src_t *s, const char *log);
/*! ocv_gl_src_compile() : compiles and links s as a compute program. *log (may be NULL) receives a
 *  malloc'd, translated log (caller frees): the errors on failure (s->why if an add had failed), the
 *  compiler's warnings on success, or NULL when it said nothing. @return the program, or 0. */
GLuint ocv_gl_src_compile(const ocv_gl_src_t *s, char **log);
/*! ocv_gl_read_file() : the whole file at path. @return a malloc'd, NUL-terminated string (caller
 *  frees), or NULL when it cannot be opened or read (or out of memory). */
char *ocv_gl_read_file(const char *path);

/*! ocv_gl_shader_dir() : $OC_SHADER_DIR if set, else the build's OC_SHADER_DIR. */
const char *ocv_gl_shader_dir(void);
/*! ocv_gl_compute_program() : ocv_gl_src_init(defines), then the shared headers oc_port.h,
 *  sampling.h, optics.h, brick.h, atmosphere.h and the kernel file, all read from the shader
 *  directory and named "shaders/FILE", compiled by ocv_gl_src_compile(). Compiler messages name the
 *  file and line ("shaders/optics.h:12(5): error: ...").
 *  @return the program, or 0 with the (translated) log or the read error in why. */
GLuint ocv_gl_compute_program(const char *kernel, const char *defines, char *why, size_t why_len);

/* ---- GPU state (gl_state.c) ------------------------------------------------------------------------- */

/*! GPU bytes per node record are OC_RECORD_BYTES (the std430 leaf record, oc_budget.h); per interior
 *  node of the pointer octree: */
#define OCV_GL_INNER_BYTES 32u
/*! Deepest octree-map level (64³ references): see gl_state.c. */
#define OCV_GL_MAP_MAX_LEVEL 6
/* GPU bytes per brick slot in the atlas (8³ texels of RG16UI) are OC_SLOT_BYTES (oc_budget.h). */

typedef struct {
  GLuint atlas;         /**< GL_TEXTURE_3D, RG16UI: (σt code, τ code) per sample; 0 without bricks */
  int atlas_bricks[3];  /**< bricks per axis; brick slot s sits at (s % x, s / x % y, s / (x·y)) · 8 */
  GLuint tree;          /**< SSBO of uint: word 0 the root reference, then 8 child references per interior
                             node, then the octree map (8^map_level references, x fastest) */
  uint32_t map_offset;  /**< word of the map in tree */
  int map_level;        /**< 0: no map; else the level whose cells the map resolves */
  uint64_t tree_bytes;  /**< of tree, map included */
  GLuint leaves;        /**< SSBO of leaf records (README.md) */
  uint32_t inner_count; /**< interior nodes of the pointer octree */
  uint32_t leaf_count;  /**< = the state's node_count */
  uint32_t brick_count;
  uint64_t resident_bytes; /**< atlas + tree + leaf records actually allocated on the GPU */
  oc_dvec3 sun_dir;        /**< the state's sun */
  int shared_atlas;        /**< the atlas belongs to an ocv_gl_store_t: ocv_gl_state_free() keeps it */
  uint64_t serial;         /**< this GPU copy's serial number (never 0, never reused): what the renderer's
                                cloud shadow volume was built from */
} ocv_gl_state_t;

/*! ocv_gl_state_upload() : the GPU copy of a validated state (gs is overwritten; free it first if it
 *  held one). @return 0, OC_ETOOBIG (atlas larger than GL_MAX_3D_TEXTURE_SIZE allows), OC_ENOMEM, or
 *  OC_ECORRUPT for leaves that do not partition the root cube. */
int ocv_gl_state_upload(ocv_gl_state_t *gs, const oc_state_t *s, char *why, size_t why_len);
void ocv_gl_state_free(ocv_gl_state_t *gs);

/* ---- Kept states (gl_store.c) ------------------------------------------------------------------------ */

/* The viewer's GPU memory across epochs (design.md, Conventions: state, budget): one brick atlas
 * sized from the granted budget, shared by the kept states, each brick uploaded once however many
 * states reference it (brick ids name one content); node records and the pointer octree per state.
 * A new state is staged, its missing bricks are uploaded a bounded number of bytes per call (so a
 * big epoch never stalls a frame), and only when all are resident does it become the newest kept
 * state; the oldest beyond `kept` is dropped and bricks no kept state references free their slots. */
typedef struct ocv_gl_store_s ocv_gl_store_t;

typedef struct {
  uint32_t capacity, used;           /**< atlas slots */
  uint32_t pending;                  /**< bricks of the staged state still to upload */
  uint32_t ready;                    /**< complete states kept */
  uint64_t uploaded_bricks, uploaded_bytes;
  uint64_t resident_bytes;           /**< the Conventions' measure: distinct bricks of the kept and the
                                          staged states × the grant's slot bytes + their records × its
                                          record bytes: what the server counts */
  uint64_t gpu_bytes;                /**< what is allocated: the atlas, trees and leaf buffers */
} ocv_gl_store_stats_t;

/*! ocv_gl_store_create() : an atlas of oc_budget_slots(grant) bricks (the most a window within the
 *  grant can hold: its records taken off), and K − 1 complete states kept beside the staged one
 *  (2 animated, 1 static). NULL with why on failure (a grant below oc_budget_min(), K not 2..3). */
ocv_gl_store_t *ocv_gl_store_create(const oc_budget_t *grant, char *why, size_t why_len);
void ocv_gl_store_free(ocv_gl_store_t *st);
/*! ocv_gl_store_stage() : s (validated; it must stay unchanged until it is ready) becomes the state
 *  being uploaded, replacing one still staged. @return 0, or OC_ETOOBIG (its new bricks do not fit
 *  the atlas beside the kept states: more than the budget) / OC_ENOMEM with why. */
int ocv_gl_store_stage(ocv_gl_store_t *st, const oc_state_t *s, char *why, size_t why_len);
/*! ocv_gl_store_pump() : uploads at most max_bytes of the staged state's bricks (at least one).
 *  @return 1 when the staged state became ready (now ocv_gl_store_state(st, 0)), 0 when bricks
 *  remain or nothing is staged, or a negative OC_E* with why. */
int ocv_gl_store_pump(ocv_gl_store_t *st, uint64_t max_bytes, char *why, size_t why_len);
/*! ocv_gl_store_state() : the i-th newest ready state (0: newest), or NULL. */
const ocv_gl_state_t *ocv_gl_store_state(const ocv_gl_store_t *st, int i);
void ocv_gl_store_stats(const ocv_gl_store_t *st, ocv_gl_store_stats_t *out);

/* ---- Raymarch (gl_render.c) --------------------------------------------------------------------------- */

typedef struct ocv_gl_renderer_s ocv_gl_renderer_t;

/*! ocv_gl_renderer_create() : compiles shaders/raymarch.comp.glsl. @return NULL with why on failure. */
ocv_gl_renderer_t *ocv_gl_renderer_create(char *why, size_t why_len);
void ocv_gl_renderer_free(ocv_gl_renderer_t *r);

/*! ocv_gl_render_state() : renders gs with the model of oc_render_state() (same desc, same defaults
 *  and checks; desc->threads is ignored) into img (w×h of desc): linear RGB radiance and cloud
 *  transmittance, before tone mapping. The atmosphere tables of desc->atmo are uploaded on first use
 *  and kept while the same tables are passed. @return 0, or OC_EINVAL / OC_ENOMEM / OC_EIO with why. */
int ocv_gl_render_state(ocv_gl_renderer_t *r, const ocv_gl_state_t *gs, const oc_render_desc_t *desc, oc_image_t *img,
                        char *why, size_t why_len);
/*! ocv_gl_renderer_output() : the GL buffer holding the last ocv_gl_render_state() image (w×h RGBA32F,
 *  rows from the top), 0 before the first. img may be NULL there to keep the image on the GPU. */
GLuint ocv_gl_renderer_output(const ocv_gl_renderer_t *r);

/*! ocv_gl_renderer_set_map() : use the states' octree maps (on, the default) or descend every lookup
 *  from the root (off: the same image, for benchmarks and tests). */
void ocv_gl_renderer_set_map(ocv_gl_renderer_t *r, int on);

/*! ocv_gl_renderer_set_variants() : compile one kernel per combination of the features a frame uses
 *  (atmosphere, blending, a debug view) with the others left out (on, the default), or always use the
 *  generic kernel that branches on uniforms (off: the same image, for benchmarks). A variant is
 *  compiled when first used; the common one (atmosphere only) when the renderer is created. */
void ocv_gl_renderer_set_variants(ocv_gl_renderer_t *r, int on);

/*! ocv_gl_renderer_set_shadow_age() : keep the cloud shadow volume (shaders/shadow.h) for a new state
 *  while it is younger than max_age_s, at time now_s (s, any monotonic clock), instead of rerunning
 *  its pass; a new sun or grid option, the camera leaving the grid's centre region, or no volume yet
 *  still rebuild it at once. The clouds' own τ comes from the new state either way; only shadows in
 *  empty leaves lag. 0 (the default): rebuilt for every new state, the one-shot render exactly. The
 *  view sets OCV_GL_SHADOW_MAX_AGE_S around each frame when it has a frame-time target. */
void ocv_gl_renderer_set_shadow_age(ocv_gl_renderer_t *r, double max_age_s, double now_s);
#define OCV_GL_SHADOW_MAX_AGE_S 5.0
/*! ocv_gl_renderer_set_shadow_slices() : build a new cloud shadow volume over `slices` renders, a slice
 *  each (an interleaved 1/slices of its texel rows), into a second buffer while the old volume is read,
 *  read from the render of its last slice on; ≤ 1 (the default): built whole before the render that
 *  needs it, the one-shot render exactly. Built whole either way without a volume or with other grid
 *  options. A slice runs with the state of its render (a volume spread over states is stale for a
 *  new state as an old one is), with the sun and camera of the first. The view sets
 *  OCV_GL_SHADOW_SLICES around each frame when it has a frame-time target. */
void ocv_gl_renderer_set_shadow_slices(ocv_gl_renderer_t *r, int slices);
#define OCV_GL_SHADOW_SLICES 8
/*! ocv_gl_renderer_shadow_passes() : how many shadow volumes r has begun to build (tests). */
uint64_t ocv_gl_renderer_shadow_passes(const ocv_gl_renderer_t *r);
/*! ocv_gl_renderer_shadow_texels() : how many texels r's shadow passes have written (tests). */
uint64_t ocv_gl_renderer_shadow_texels(const ocv_gl_renderer_t *r);
/*! ocv_gl_renderer_shadow_read() : the texels of the shadow volume read by the last render (shaders/shadow.h's
 *  order) into out when n holds them (tests). @return their count, 0 without a volume. */
size_t ocv_gl_renderer_shadow_read(const ocv_gl_renderer_t *r, float *out, size_t n);

/*! ocv_gl_renderer_timings() : GPU time of the last trace and reprojection passes (timer queries),
 *  ms; −1 for a pass not run yet. */
void ocv_gl_renderer_timings(const ocv_gl_renderer_t *r, double *trace_ms, double *reproject_ms);

/* ---- Interpolation between states (gl_interp.c) -------------------------------------------------------- */

/* The previous value of every leaf of the newest state (client/interp.h) on the GPU: per-leaf records
 * (SSBO binding 4: vec4 uniform σt, τ; uvec4 blend, uniform, pool entry, fine) and the pool of
 * resampled bricks as an RG32F 3D texture (unit 5; a fine, merged leaf has 8 consecutive entries, one
 * per octant). The kernel shows mix(previous, newest, t) where a leaf blends (design.md, Conventions:
 * interpolation). */
typedef struct {
  GLuint records, pool;
  int pool_bricks[3];
  uint32_t count, pool_count;
  uint64_t gpu_bytes;
} ocv_gl_prev_t;

/*! ocv_gl_prev_upload() : the previous values of `ip` (an ocv_interp_t built for the state that will
 *  be rendered); `animated` chooses the weights (ocv_interp_weight: static scenes blend only split
 *  and merged leaves). gp is overwritten. @return 0 or OC_ENOMEM / OC_ETOOBIG with why. */
int ocv_gl_prev_upload(ocv_gl_prev_t *gp, const ocv_interp_t *ip, int animated, char *why, size_t why_len);
void ocv_gl_prev_free(ocv_gl_prev_t *gp);
/*! ocv_gl_renderer_set_prev() : later renders blend with gp at parameter t ∈ [0, 1] (1: the newest
 *  state only); NULL switches blending off. gp must match the state rendered and outlive its use. */
void ocv_gl_renderer_set_prev(ocv_gl_renderer_t *r, const ocv_gl_prev_t *gp, float t);

/* ---- Reprojection (gl_render.c, shaders/reproject.comp.glsl) ------------------------------------------ */

/* A view's history for rendering one pixel in 16 per frame: each frame traces one position of every
 * 4×4 block (Bayer order) and fills the others from the previous frame, reprojected through the
 * depth it stored (where the cloud transmittance first fell below ½, else the ground, else far);
 * history whose depth disagrees with the reprojected point's is rejected and the block's freshly
 * traced pixel is used instead. While the camera moves, far history is also rejected where a nearer
 * surface now covers it: farther than all four traced pixels bracketing it, or beside nearer history
 * that, reprojected at its depth, lands on itself (parallax at a cloud's leading edge). With a still
 * camera every pixel is fresh after 16 frames. */
typedef struct ocv_gl_history_s ocv_gl_history_t;

typedef struct {
  uint32_t traced, reprojected; /**< pixels of the frame: traced now, taken from the history */
  uint32_t rejected;            /**< filled from their block's traced pixel (no history, off screen,
                                     or depth disagreed) */
} ocv_gl_frame_stats_t;

ocv_gl_history_t *ocv_gl_history_create(int w, int h, char *why, size_t why_len);
void ocv_gl_history_free(ocv_gl_history_t *hs);
/*! ocv_gl_history_reset() : forget the history (a new state, a teleport). */
void ocv_gl_history_reset(ocv_gl_history_t *hs);
/*! ocv_gl_history_refresh() : a new state whose first frames continue the picture (blended from the
 *  state before): the history is kept, but a pixel taken from it whose block position was not traced
 *  since is clamped to the range of the pixels traced around it in that frame (the 3×3 blocks), so
 *  what the new state changes shows in the first frame instead of 4×4 blocks filled from one traced
 *  pixel; after 16 frames every position was traced again and nothing is clamped. */
void ocv_gl_history_refresh(ocv_gl_history_t *hs);
/*! ocv_gl_render_frame() : one frame of desc's view into img (the history's size); reproject 0
 *  traces every pixel (and keeps it as history). @return 0 or a negative OC_E* with why. */
int ocv_gl_render_frame(ocv_gl_renderer_t *r, ocv_gl_history_t *hs, const ocv_gl_state_t *gs, const oc_render_desc_t *desc,
                        int reproject, oc_image_t *img, ocv_gl_frame_stats_t *fs, char *why, size_t why_len);
/*! ocv_gl_history_output() : the GL buffer holding the newest frame (as ocv_gl_renderer_output()), 0
 *  before the first. img may be NULL in ocv_gl_render_frame() to keep the frame on the GPU. */
GLuint ocv_gl_history_output(const ocv_gl_history_t *hs);

/* ---- The viewer's frame loop (gl_view.c) ---------------------------------------------------------------- */

/* What overcast-view does every frame, without a window, so it can be tested headless: states that
 * arrived are staged into the kept-state store (uploads bounded per frame), a state that became
 * complete is shown from then on with the previous values of its leaves (the state shown before it)
 * and blended in over one epoch period, optionally one pixel in 16 is traced (reprojection). */
typedef struct ocv_gl_view_s ocv_gl_view_t;

typedef struct {
  oc_budget_t grant;           /**< WELCOME's grant: the store (ocv_gl_store_create()) is sized from it
                                    and keeps K − 1 complete states (2 animated, 1 static) */
  int animated;                /**< time interpolation (else only splits and merges cross-fade) */
  double epoch_period;         /**< s; the blend lasts the wall time between the two states'
                                    epochs (ocv_interp_blend_seconds; ≤ 0: no blend) */
  uint64_t upload_per_frame;   /**< bytes of bricks uploaded per frame; 0 → 4 MiB. With a frame-time
                                    target, in steps of a sixteenth of it (256 KiB) for as long as they
                                    have taken less than a quarter of the target (one step at least) */
  double frame_ms;             /**< frame-time target, ms: the view traces at full, 1/2, 1/4 or 1/8 of
                                    desc's size per axis, chosen from the frame times reported
                                    (ocv_gl_view_frame_time), and the picture is upsampled
                                    (ocv_gl_present_upsample), and a new state reuses a cloud
                                    shadow volume younger than OCV_GL_SHADOW_MAX_AGE_S
                                    (ocv_gl_renderer_set_shadow_age), a rebuild spread over
                                    OCV_GL_SHADOW_SLICES frames (ocv_gl_renderer_set_shadow_slices);
                                    0: off, every frame at full size, the shadow volume rebuilt
                                    whole for every new state */
} ocv_gl_view_desc_t;

typedef struct {
  uint64_t epoch;        /**< of the state shown (0 before the first) */
  float t;               /**< its blend parameter */
  uint32_t pending;      /**< bricks of the staged state still to upload */
  uint64_t uploaded_bytes; /**< this frame */
  uint64_t resident_bytes; /**< the Conventions' measure (ocv_gl_store_stats) */
  uint32_t bricks;       /**< atlas slots in use */
  ocv_gl_frame_stats_t frame;
  int shown;             /**< 1 when a state was rendered */
  int switched;          /**< 1 when this frame switched to a state that became complete */
  int scale;             /**< the divisor per axis the frame was traced at (1, 2, 4, 8) */
  int trace_w, trace_h;  /**< the traced size (ocv_gl_view_output's) */
} ocv_gl_view_stats_t;

ocv_gl_view_t *ocv_gl_view_create(ocv_gl_renderer_t *r, const ocv_gl_view_desc_t *d, char *why, size_t why_len);
void ocv_gl_view_free(ocv_gl_view_t *v);
/*! ocv_gl_view_push() : a new complete state (copied), replacing one still being uploaded.
 *  @return 0 or a negative OC_E* with why (OC_ETOOBIG: it does not fit the budget). */
int ocv_gl_view_push(ocv_gl_view_t *v, const oc_state_t *s, char *why, size_t why_len);
/*! ocv_gl_view_staging() : 1 while a pushed state is still being uploaded. A caller that pushes
 *  every newer state before the last completes may never see one complete when a frame uploads
 *  less than a state's new bricks (llvmpipe at 1280×720: 20–60 s a frame); it waits for 0 instead. */
int ocv_gl_view_staging(const ocv_gl_view_t *v);
/*! ocv_gl_view_frame() : one frame at time `now` (s, any monotonic clock): pumps uploads, switches
 *  to a state that became complete, renders desc's view (blended, reprojected when asked) into img.
 *  Before the first state is complete nothing is rendered (stats->shown 0). @return 0 or OC_E*. */
int ocv_gl_view_frame(ocv_gl_view_t *v, const oc_render_desc_t *desc, double now, int reproject, oc_image_t *img,
                      ocv_gl_view_stats_t *st, char *why, size_t why_len);
/*! ocv_gl_view_output() : the GL buffer of the last frame rendered (trace_w×trace_h RGBA32F radiance,
 *  rows from the top; desc's w×h unless a frame-time target scales it), 0 before the first; img may
 *  be NULL in ocv_gl_view_frame() to keep frames on the GPU. */
GLuint ocv_gl_view_output(const ocv_gl_view_t *v);

/* The frame-time target (ocv_gl_view_desc_t.frame_ms): the traced size is desc's divided by 1, 2, 4
 * or 8 per axis (rounded, the coarsest keeping ≥ OCV_GL_SCALE_MIN_ROWS rows). A frame is about 4×
 * cheaper per step, so the controller keeps a wide band between the two decisions and never flickers:
 * coarser when two frames in a row took more than 1.25× the target (or one more than 3×), as many
 * steps as bring the time predicted (∝ pixels) under 0.7×; finer when three frames in a row would
 * still fit 0.6× of it at the finer scale (time × 4). Frames that switched state or showed nothing
 * are not counted. The first frame is traced at the coarsest scale (llvmpipe: 160×90 for 1280×720),
 * which a fast GPU leaves within a few frames. */
#define OCV_GL_SCALE_MAX 8
#define OCV_GL_SCALE_MIN_ROWS 32
/*! ocv_gl_view_frame_time() : the wall time of the whole last frame, ms (render, upload, picture,
 *  swap: what the caller measured around its loop), for the controller; a test may report any time
 *  (a slow frame made up). No-op without a target. */
void ocv_gl_view_frame_time(ocv_gl_view_t *v, double ms);
/*! ocv_gl_view_scale() : the divisor per axis (1, 2, 4, 8) the next frame of a view h rows high traces
 *  at (1 without a target). */
int ocv_gl_view_scale(const ocv_gl_view_t *v, int h);
/*! ocv_gl_view_trace_size() : the size traced for a w×h view at divisor `scale` (≥ 1×1). */
void ocv_gl_view_trace_size(int w, int h, int scale, int *tw, int *th);

/* ---- The picture (gl_present.c, shaders/present.comp.glsl) --------------------------------------------- */

/* Tone mapping and the HUD on the GPU, so a window's frame never makes the GPU → CPU → GPU round trip:
 * exposure, ACES fit and sRGB from shaders/optics.h (the CPU's oc_image_tonemap() runs the same
 * code), then a premultiplied RGBA8 overlay (ocv_hud_text_rgba) composited over the top-left corner. */
typedef struct ocv_gl_present_s ocv_gl_present_t;

ocv_gl_present_t *ocv_gl_present_create(char *why, size_t why_len);
void ocv_gl_present_free(ocv_gl_present_t *p);
/*! ocv_gl_present_tonemap() : tone maps `radiance` (a w×h RGBA32F buffer, e.g. ocv_gl_view_output())
 *  with `exposure` and composites `overlay` (ow×oh premultiplied RGBA8 rows from the top, placed at the
 *  top-left; NULL for none) into an RGBA8 texture of w×h. @return the texture (rows from the top,
 *  valid until the next call), or 0 with why. */
GLuint ocv_gl_present_tonemap(ocv_gl_present_t *p, GLuint radiance, int w, int h, float exposure, const uint8_t *overlay,
                              int ow, int oh, char *why, size_t why_len);
/*! ocv_gl_present_upsample() : as ocv_gl_present_tonemap() for a radiance buffer of rw×rh (a frame traced
 *  at a lower resolution), bilinearly interpolated (texel centres aligned, edges clamped) to the w×h
 *  picture before tone mapping; rw×rh = w×h is ocv_gl_present_tonemap() exactly. */
GLuint ocv_gl_present_upsample(ocv_gl_present_t *p, GLuint radiance, int rw, int rh, int w, int h, float exposure,
                               const uint8_t *overlay, int ow, int oh, char *why, size_t why_len);
/*! ocv_gl_present_read() : the last tone-mapped picture as 8-bit RGB rows from the top (w·h·3 bytes, the
 *  layout of oc_image_tonemap()), for screenshots and tests. @return 0, or OC_EINVAL before the first. */
int ocv_gl_present_read(ocv_gl_present_t *p, uint8_t *rgb8, char *why, size_t why_len);

#endif /* OC_CLIENT_GL_H */
