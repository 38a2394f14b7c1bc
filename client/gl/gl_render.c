/* gl_render.c — the raymarch compute pass: oc_render_state()'s model on the GPU
 * (shaders/raymarch.comp.glsl), same description, same defaults, same output (linear radiance and
 * cloud transmittance, before tone mapping).
 *
 * Everything the shader needs in double precision is reduced here, per camera, to quantities that
 * are exact or small in float (design.md, Conventions): the camera's level-21 cell (integers) and the
 * offset inside it, |o|² - R² for the spheres, o·sun, and o split into two floats for o·d. */
#include <epoxy/gl.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "oc_planet.h"
#include "ocv_gl.h"

_Static_assert(sizeof(ocg_atmosphere) == 96, "ocg_atmosphere is the std140 block of the shader");

#define OCV__KERNEL "raymarch.comp.glsl"
#define OCV__GROUP 8 /* local_size_x/y of the kernel */

/* Shader variants: bit 0 atmosphere, bit 1 blending, bit 2 a debug view (raymarch.comp.glsl's OCV_ATMO,
 * OCV_BLEND, OCV_DEBUG); OCV__GENERIC is the program reading them from uniforms. */
#define OCV__VARIANTS 8
#define OCV__GENERIC OCV__VARIANTS

/* A cloud shadow volume: its buffer, and the state, sun and camera its shadow pass runs for. */
typedef struct {
  GLuint buf;
  size_t bytes;
  oc_shadow_frame_t f; /* where it is (f.n[0] = 0: none) */
  uint64_t serial;     /* the state it was begun from (ocv_gl_state_t.serial), 0: none yet */
  int mixed;           /* a slice ran on a later state than serial (the window only) */
  oc_dvec3 sun;
  double built;        /* when it was completed, in sh_now's clock */
  int ic[3];           /* the camera's level-21 cell and offset, and its position: the pass's uniforms */
  double fr[3];
  oc_dvec3 cam;
  int slices, done;    /* it is built in `slices` passes, `done` of them run */
} ocv__shvol_t;

struct ocv_gl_renderer_s {
  GLuint prog[OCV__VARIANTS + 1]; /* compiled on first use, but for the common one at creation */
  char defines[512];
  char sh_defines[600];           /* defines + OCV_SHADOW_PASS */
  int generic;                    /* always the generic program (benchmarks) */
  GLuint atmo_ubo;
  GLuint tab[OC_ATMO_TABLE_COUNT];
  const oc_atmo_t *atmo; /* whose tables tab[] hold */
  GLuint out, depth;
  size_t out_bytes, depth_bytes;
  GLuint reproject; /* shaders/reproject.comp.glsl */
  const ocv_gl_prev_t *prev; /* blending on when set */
  float t;
  GLuint query[2];       /* GL_TIME_ELAPSED of the trace and the reprojection pass */
  double pass_ms[2];     /* the last measured, < 0 before the first */
  int no_map;            /* descend from the root (benchmarks, tests) */
  /* The cloud shadow volume (shaders/shadow.h), built by the kernel's shadow pass: sh[sh_cur] is read,
   * the other one is built over frames while sh_building (ocv_gl_renderer_set_shadow_slices). */
  GLuint sh_prog;
  ocv__shvol_t sh[2];
  int sh_cur, sh_building;
  int sh_slices;             /* frames a rebuild is spread over; ≤ 1: built whole (one-shot) */
  double sh_max_age, sh_now; /* a volume this young (s) is kept for a new state; 0: rebuilt (one-shot) */
  uint64_t sh_passes;        /* shadow volumes begun */
  uint64_t sh_texels;        /* texels written by shadow passes */
};

void ocv_gl_renderer_set_shadow_age(ocv_gl_renderer_t *r, double max_age_s, double now_s) {
  if (!r) return;
  r->sh_max_age = max_age_s > 0.0 && isfinite(max_age_s) ? max_age_s : 0.0;
  r->sh_now = now_s;
}

void ocv_gl_renderer_set_shadow_slices(ocv_gl_renderer_t *r, int slices) {
  if (r) r->sh_slices = slices > 1 ? slices : 1;
}

uint64_t ocv_gl_renderer_shadow_passes(const ocv_gl_renderer_t *r) { return r ? r->sh_passes : 0; }

uint64_t ocv_gl_renderer_shadow_texels(const ocv_gl_renderer_t *r) { return r ? r->sh_texels : 0; }

/* The texels of frame f's grids: the volume's, then the ground map's. */
static size_t ocv__shadow_count(const oc_shadow_frame_t *f) {
  return (size_t)f->n[0] * (size_t)f->n[1] * (size_t)f->n[2] + (size_t)f->ground_n * (size_t)f->ground_n;
}

size_t ocv_gl_renderer_shadow_read(const ocv_gl_renderer_t *r, float *out, size_t n) {
  const ocv__shvol_t *v = r ? &r->sh[r->sh_cur] : NULL;
  size_t have = v && v->serial ? ocv__shadow_count(&v->f) : 0;
  if (have && out && n >= have) glGetNamedBufferSubData(v->buf, 0, (GLsizeiptr)(have * sizeof(float)), out);
  return have;
}

void ocv_gl_renderer_set_map(ocv_gl_renderer_t *r, int on) {
  if (r) r->no_map = !on;
}

void ocv_gl_renderer_timings(const ocv_gl_renderer_t *r, double *trace_ms, double *reproject_ms) {
  if (trace_ms) *trace_ms = r ? r->pass_ms[0] : -1.0;
  if (reproject_ms) *reproject_ms = r ? r->pass_ms[1] : -1.0;
}

/* GPU time of the pass just dispatched. Mesa's llvmpipe reports about 0 for compute dispatches;
 * a GPU reports the pass. */
static void ocv__time_begin(ocv_gl_renderer_t *r, int k) {
  if (!r->query[k]) glCreateQueries(GL_TIME_ELAPSED, 1, &r->query[k]);
  glBeginQuery(GL_TIME_ELAPSED, r->query[k]);
}
static void ocv__time_end(ocv_gl_renderer_t *r, int k) {
  glEndQuery(GL_TIME_ELAPSED);
  GLuint64 ns = 0;
  glGetQueryObjectui64v(r->query[k], GL_QUERY_RESULT, &ns);
  r->pass_ms[k] = 1e-6 * (double)ns;
}

void ocv_gl_renderer_set_prev(ocv_gl_renderer_t *r, const ocv_gl_prev_t *gp, float t) {
  if (!r) return;
  r->prev = gp;
  r->t = t < 0.0f ? 0.0f : t > 1.0f ? 1.0f : t;
}

/* The kernel for variant v (or the generic one), compiled the first time it is asked for. */
static GLuint ocv__program(ocv_gl_renderer_t *r, int v, char *why, size_t why_len) {
  if (r->prog[v]) return r->prog[v];
  char defines[1024];
  if (v == OCV__GENERIC)
    snprintf(defines, sizeof defines, "%s", r->defines);
  else
    snprintf(defines, sizeof defines, "%s#define OCV_ATMO %s\n#define OCV_BLEND %s\n#define OCV_DEBUG %s\n", r->defines,
             v & 1 ? "true" : "false", v & 2 ? "true" : "false", v & 4 ? "true" : "false");
  r->prog[v] = ocv_gl_compute_program(OCV__KERNEL, defines, why, why_len);
  return r->prog[v];
}

void ocv_gl_renderer_set_variants(ocv_gl_renderer_t *r, int on) {
  if (r) r->generic = !on;
}

ocv_gl_renderer_t *ocv_gl_renderer_create(char *why, size_t why_len) {
  ocv_gl_renderer_t *r = calloc(1, sizeof *r);
  if (!r) {
    (void)oc_errorf(0, why, why_len, "out of memory");
    return NULL;
  }
  /* The flag bits and constants the kernel shares with oc_render.c, from their one definition. */
  snprintf(r->defines, sizeof r->defines,
           "#define OCV_RF_NO_AMBIENT %uu\n#define OCV_RF_NO_SUN_DISC %uu\n#define OCV_RF_JITTER %uu\n"
           "#define OCV_LOCATE_EPS 1e-4\n#define OCV_MAX_STEPS 200000\n"
           "#define OCV_DEBUG_LOD %d\n#define OCV_DEBUG_TAU %d\n#define OCV_DEBUG_BOUNDS %d\n",
           (unsigned)OC_RF_NO_AMBIENT, (unsigned)OC_RF_NO_SUN_DISC, (unsigned)OC_RF_JITTER, OC_DEBUG_LOD, OC_DEBUG_TAU,
           OC_DEBUG_BOUNDS);
  snprintf(r->sh_defines, sizeof r->sh_defines, "%s#define OCV_SHADOW_PASS 1\n", r->defines);
  r->pass_ms[0] = r->pass_ms[1] = -1.0;
  GLuint common = ocv__program(r, 1, why, why_len); /* atmosphere, no blend, no debug view */
  if (common) r->reproject = ocv_gl_compute_program("reproject.comp.glsl", NULL, why, why_len);
  if (!common || !r->reproject) {
    if (common) glDeleteProgram(common);
    free(r);
    return NULL;
  }
  ocg_atmosphere zero;
  memset(&zero, 0, sizeof zero);
  glCreateBuffers(1, &r->atmo_ubo);
  glNamedBufferStorage(r->atmo_ubo, sizeof zero, &zero, GL_DYNAMIC_STORAGE_BIT);
  return r;
}

static void ocv__drop_tables(ocv_gl_renderer_t *r) {
  for (int k = 0; k < OC_ATMO_TABLE_COUNT; k++)
    if (r->tab[k]) glDeleteTextures(1, &r->tab[k]);
  memset(r->tab, 0, sizeof r->tab);
  r->atmo = NULL;
}

void ocv_gl_renderer_free(ocv_gl_renderer_t *r) {
  if (!r) return;
  ocv__drop_tables(r);
  if (r->atmo_ubo) glDeleteBuffers(1, &r->atmo_ubo);
  if (r->out) glDeleteBuffers(1, &r->out);
  if (r->depth) glDeleteBuffers(1, &r->depth);
  for (int v = 0; v <= OCV__VARIANTS; v++)
    if (r->prog[v]) glDeleteProgram(r->prog[v]);
  if (r->reproject) glDeleteProgram(r->reproject);
  if (r->sh_prog) glDeleteProgram(r->sh_prog);
  for (int k = 0; k < 2; k++)
    if (r->sh[k].buf) glDeleteBuffers(1, &r->sh[k].buf);
  for (int k = 0; k < 2; k++)
    if (r->query[k]) glDeleteQueries(1, &r->query[k]);
  free(r);
}

/* The four tables as RGBA32F textures, sampled with texelFetch (the shader interpolates exactly as
 * oc_atmo's look-ups do, rather than trusting the hardware's filter weights). */
static int ocv__upload_tables(ocv_gl_renderer_t *r, const oc_atmo_t *a) {
  if (r->atmo == a) return 0;
  ocv__drop_tables(r);
  for (int k = 0; k < OC_ATMO_TABLE_COUNT; k++) {
    int w = 0, h = 0;
    const float *px = NULL;
    if (oc_atmo_table(a, k, &w, &h, &px) < 0) return OC_EINVAL;
    glCreateTextures(GL_TEXTURE_2D, 1, &r->tab[k]);
    glTextureParameteri(r->tab[k], GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(r->tab[k], GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTextureStorage2D(r->tab[k], 1, GL_RGBA32F, w, h);
    glTextureSubImage2D(r->tab[k], 0, 0, 0, w, h, GL_RGBA, GL_FLOAT, px);
  }
  glNamedBufferSubData(r->atmo_ubo, 0, sizeof(ocg_atmosphere), oc_atmo_params(a));
  r->atmo = a;
  return 0;
}

static int ocv__bad(char *why, size_t wl, const char *field) {
  (void)oc_errorf(0, why, wl, "gl render: invalid %s", field);
  return OC_EINVAL;
}

/* A device buffer of exactly `bytes` (re-created when the size changes). */
static void ocv__buffer(GLuint *b, size_t *have, size_t bytes);

/* Whether volume v has the grids of frame f (their sizes, spacings and bottom: the options). */
static int ocv__shadow_same_grid(const ocv__shvol_t *v, const oc_shadow_frame_t *f) {
  const oc_shadow_frame_t *o = &v->f;
  return !memcmp(o->n, f->n, sizeof o->n) && !memcmp(o->cell, f->cell, sizeof o->cell) && o->lo[2] == f->lo[2] &&
         o->ground_n == f->ground_n && o->ground_cell == f->ground_cell;
}

/* Whether the shadow volume v must be rebuilt for frame f: a new sun or grid, the camera over an eighth
 * of its edge from its centre, none yet, or a new state (or one built from several) unless the volume
 * is younger than sh_max_age (the window's frame loop; ocv_gl_renderer_set_shadow_age). */
static int ocv__shadow_stale(const ocv_gl_renderer_t *r, const ocv__shvol_t *v, const ocv_gl_state_t *gs,
                             const oc_shadow_frame_t *f) {
  if (!v->serial || memcmp(&v->sun, &gs->sun_dir, sizeof v->sun) || !ocv__shadow_same_grid(v, f)) return 1;
  if (v->serial != gs->serial || v->mixed) {
    double age = r->sh_now - v->built;
    if (!(r->sh_max_age > 0.0 && age >= 0.0 && age < r->sh_max_age)) return 1;
  }
  return f->n[0] && oc_dlen(oc_dsub(v->f.c0, f->c0)) > 0.125 * (f->n[0] - 1) * f->cell[0];
}

/* Sets the shadow volume's uniforms on program p (the camera o in its frame). */
static void ocv__shadow_uniforms(GLuint p, const oc_shadow_frame_t *f, oc_dvec3 o) {
  oc_dvec3 d = oc_dsub(o, f->c0);
  glProgramUniform3f(p, 37, (float)f->lo[0], (float)f->lo[1], (float)f->lo[2]);
  glProgramUniform3f(p, 38, (float)f->cell[0], (float)f->cell[1], (float)f->cell[2]);
  glProgramUniform3i(p, 39, f->n[0], f->n[1], f->n[2]);
  glProgramUniform3f(p, 40, (float)oc_ddot(d, f->east), (float)oc_ddot(d, f->north), (float)oc_ddot(d, f->up));
  glProgramUniform3f(p, 41, (float)f->east.x, (float)f->east.y, (float)f->east.z);
  glProgramUniform3f(p, 42, (float)f->north.x, (float)f->north.y, (float)f->north.z);
  glProgramUniform3f(p, 43, (float)f->up.x, (float)f->up.y, (float)f->up.z);
  glProgramUniform1i(p, 45, f->ground_n);
  glProgramUniform1f(p, 46, (float)f->ground_cell);
}

/* Work groups along y of slice s of v: the rows of groups (OCV__GROUP texel rows each) s, s + slices,
 * s + 2·slices, … of the texel rows of n_x texels, the volume's n_y·n_z and then the ground map's n² texels
 * in memory order (the last row may be short); *texels: the texels they write. */
static int ocv__slice_groups(const ocv__shvol_t *v, int s, uint64_t *texels) {
  const int64_t nx = v->f.n[0], all = (int64_t)ocv__shadow_count(&v->f);
  int rows = (int)((all + nx - 1) / nx), groups = (rows + OCV__GROUP - 1) / OCV__GROUP;
  int mine = s < groups ? (groups - 1 - s) / v->slices + 1 : 0;
  *texels = 0;
  for (int64_t g = s; g < groups; g += v->slices) {
    int64_t first = g * OCV__GROUP * nx, end = (g + 1) * OCV__GROUP * nx;
    *texels += (uint64_t)((end < all ? end : all) - first);
  }
  return mine;
}

/* The next slice of v's shadow pass on the state gs, with the sun and camera v was begun for. */
static int ocv__shadow_slice(ocv_gl_renderer_t *r, const ocv_gl_state_t *gs, ocv__shvol_t *v, char *why, size_t why_len) {
  if (!r->sh_prog) r->sh_prog = ocv_gl_compute_program(OCV__KERNEL, r->sh_defines, why, why_len);
  if (!r->sh_prog) return OC_EIO;
  GLuint q = r->sh_prog;
  int s = v->done++;
  uint64_t texels;
  int mine = ocv__slice_groups(v, s, &texels);
  if (gs->serial != v->serial) v->mixed = 1;
  ocv__shadow_uniforms(q, &v->f, v->cam);
  glProgramUniform3i(q, 0, v->ic[0], v->ic[1], v->ic[2]);
  glProgramUniform3f(q, 1, (float)v->fr[0], (float)v->fr[1], (float)v->fr[2]);
  glProgramUniform3f(q, 10, (float)v->sun.x, (float)v->sun.y, (float)v->sun.z);
  glProgramUniform1f(q, 12, (float)OC_CELL21_SIZE);
  glProgramUniform3i(q, 28, gs->atlas_bricks[0], gs->atlas_bricks[1], gs->atlas_bricks[2]);
  glProgramUniform1i(q, 34, r->no_map ? 0 : gs->map_level);
  glProgramUniform1ui(q, 35, gs->map_offset);
  glProgramUniform2i(q, 44, s, v->slices);
  glProgramUniform1f(q, 23, (float)oc_dlen(v->f.c0)); /* the ground map's ground */
  glUseProgram(q);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, gs->tree);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, gs->leaves);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, v->buf);
  glBindTextureUnit(0, gs->atlas);
  if (mine) glDispatchCompute((GLuint)((v->f.n[0] + OCV__GROUP - 1) / OCV__GROUP), (GLuint)mine, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  r->sh_texels += texels;
  return 0;
}

/* The cloud shadow volume for desc's camera over a ground of radius ground_r (oc_render_state()'s),
 * bound to binding 6 with its uniforms set on the trace program p. When stale it is rebuilt (ic, fr:
 * the camera's level-21 cell and offset) into the other buffer: whole, and read at once, without a
 * volume or with other grid options or with slicing off; else one slice per call, the old volume read
 * until the last slice. */
static int ocv__shadow(ocv_gl_renderer_t *r, const ocv_gl_state_t *gs, const oc_render_desc_t *d, double ground_r, GLuint p,
                       const int ic[3], const double fr[3], char *why, size_t why_len) {
  oc_shadow_frame_t f;
  if (oc_render_shadow_frame(d, d->camera.pos, ground_r, &f) < 0) return ocv__bad(why, why_len, "shadow volume option");
  ocv__shvol_t *cur = &r->sh[r->sh_cur], *nv = &r->sh[1 - r->sh_cur];
  int whole = r->sh_slices <= 1 || !cur->serial || !ocv__shadow_same_grid(cur, &f);
  if (whole) r->sh_building = 0; /* a volume begun in slices is dropped */
  if (!r->sh_building && ocv__shadow_stale(r, cur, gs, &f)) {
    nv->f = f;
    nv->serial = gs->serial;
    nv->mixed = 0;
    nv->sun = gs->sun_dir;
    memcpy(nv->ic, ic, sizeof nv->ic);
    memcpy(nv->fr, fr, sizeof nv->fr);
    nv->cam = d->camera.pos;
    nv->slices = whole ? 1 : r->sh_slices;
    nv->done = 0;
    if (f.n[0]) ocv__buffer(&nv->buf, &nv->bytes, sizeof(float) * ocv__shadow_count(&f));
    r->sh_building = 1;
    r->sh_passes++;
  }
  if (r->sh_building) {
    if (!nv->f.n[0]) nv->done = nv->slices; /* no grid: nothing to build */
    else {
      int rc = ocv__shadow_slice(r, gs, nv, why, why_len);
      if (rc < 0) return rc;
    }
    if (nv->done == nv->slices) { /* complete: read from now on */
      nv->built = r->sh_now;
      r->sh_cur = 1 - r->sh_cur;
      r->sh_building = 0;
      cur = nv;
    }
  }
  ocv__shadow_uniforms(p, &cur->f, d->camera.pos);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, cur->f.n[0] ? cur->buf : gs->leaves); /* unread without a volume */
  return 0;
}

/* Sets the kernel's uniforms for desc and traces into out (vec4 per pixel) and depth (float per
 * pixel): every pixel (phase < 0) or those of one position in each 4×4 block (phase 0..15). */
static int ocv__dispatch(ocv_gl_renderer_t *r, const ocv_gl_state_t *gs, const oc_render_desc_t *desc, GLuint out,
                         GLuint depth, int phase, char *why, size_t why_len) {
  oc_render_desc_t d = *desc;
  /* The defaults and checks of oc_render_state(). */
  if (d.width <= 0 || d.height <= 0) return ocv__bad(why, why_len, "size");
  if (!(d.camera.vfov_deg > 0.0 && d.camera.vfov_deg < 180.0)) return ocv__bad(why, why_len, "camera fov");
  if (d.step_factor == 0.0) d.step_factor = OC_RENDER_DEFAULT_STEP_FACTOR;
  if (!(d.step_factor > 0.0 && d.step_factor <= 1e6)) return ocv__bad(why, why_len, "step_factor (0, 1e6]");
  if (d.air_steps == 0) d.air_steps = OC_RENDER_DEFAULT_AIR_STEPS;
  if (d.air_steps < 1 || d.air_steps > 1 << 20) return ocv__bad(why, why_len, "air_steps");
  if (d.exit_t == 0.0) d.exit_t = OC_RENDER_DEFAULT_EXIT_T;
  if (d.flags & OC_RF_NO_EARLY_EXIT) d.exit_t = -1.0;
  if (d.ms_octaves == 0) d.ms_octaves = OC_RENDER_DEFAULT_MS_OCTAVES;
  if (d.ms_octaves < 1 || d.ms_octaves > 16) return ocv__bad(why, why_len, "ms_octaves [1, 16]");
  if (d.ms_a == 0.0f) d.ms_a = OC_RENDER_DEFAULT_MS_A;
  if (d.ms_b == 0.0f) d.ms_b = OC_RENDER_DEFAULT_MS_B;
  if (d.ms_c == 0.0f) d.ms_c = OC_RENDER_DEFAULT_MS_C;
  if (!(d.ms_a > 0.0f && d.ms_a <= 1.0f)) return ocv__bad(why, why_len, "ms_a (0, 1]");
  if (!(d.ms_b > 0.0f && d.ms_b <= 1.0f)) return ocv__bad(why, why_len, "ms_b (0, 1]");
  if (!(d.ms_c > 0.0f && d.ms_c <= 1.0f)) return ocv__bad(why, why_len, "ms_c (0, 1]");
  if (d.ms_model != OC_MS_MODEL_DEPTH && d.ms_model != OC_MS_MODEL_OCTAVES) return ocv__bad(why, why_len, "ms_model");
  if (d.ms_fit) return ocv__bad(why, why_len, "ms_fit (CPU reference only: the shader compiles march.h's constants)");
  if (d.air_sigma != 0.0f) return ocv__bad(why, why_len, "air_sigma (CPU reference only: the truth's thin air)");
  if (d.albedo == 0.0f) d.albedo = 1.0f;
  if (d.albedo_zero) d.albedo = 0.0f;
  if (!(d.albedo >= 0.0f && d.albedo <= 1.0f)) return ocv__bad(why, why_len, "albedo [0, 1]");
  if (d.sun_irradiance == 0.0f) d.sun_irradiance = 1.0f;

  int have_atmo = d.background != OC_BG_CONSTANT && !(d.flags & OC_RF_NO_ATMOSPHERE);
  if (have_atmo && !d.atmo) return ocv__bad(why, why_len, "atmo (required with an atmosphere)");
  double air_top = OC_PLANET_RADIUS + OC_ATMOSPHERE_HEIGHT, bottom = OC_PLANET_RADIUS;
  ocg_vec3 sun_e = ocg_v3s(d.sun_irradiance);
  if (have_atmo) {
    const ocg_atmosphere *ap = oc_atmo_params(d.atmo);
    air_top = ap->top_radius;
    bottom = ap->bottom_radius;
    sun_e = ocg_scale3(ap->solar_irradiance, d.sun_irradiance);
    if (ocv__upload_tables(r, d.atmo) < 0) return ocv__bad(why, why_len, "atmo tables");
  }
  double ground_r = (d.background == OC_BG_CONSTANT || (d.flags & OC_RF_NO_PLANET)) ? 0.0 : bottom;

  /* Camera: its level-21 cell in integers and the offset inside it. */
  const oc_dvec3 o = d.camera.pos;
  const double cell = OC_CELL21_SIZE;
  double oo[3] = {o.x, o.y, o.z}, fr[3];
  int ic[3];
  for (int i = 0; i < 3; i++) {
    double c = floor((oo[i] + OC_ROOT_HALF) / cell);
    if (!(fabs(c) < 1e9)) return ocv__bad(why, why_len, "camera position");
    ic[i] = (int)c;
    fr[i] = (oo[i] + OC_ROOT_HALF) - c * cell;
  }
  double r2 = oc_ddot(o, o);
  oc_dvec3 sun = gs->sun_dir;
  float hi[3] = {(float)o.x, (float)o.y, (float)o.z};
  float lo[3] = {(float)(o.x - hi[0]), (float)(o.y - hi[1]), (float)(o.z - hi[2])};
  double tn = tan(0.5 * d.camera.vfov_deg * OC_DEG);

  int blend = r->prev && r->prev->count == gs->leaf_count && r->t < 1.0f;
  int variant = r->generic ? OCV__GENERIC : (have_atmo ? 1 : 0) | (blend ? 2 : 0) | (d.debug_view ? 4 : 0);
  GLuint p = ocv__program(r, variant, why, why_len);
  if (!p) return OC_EIO;
  glProgramUniform3i(p, 0, ic[0], ic[1], ic[2]);
  glProgramUniform3f(p, 1, (float)fr[0], (float)fr[1], (float)fr[2]);
  glProgramUniform3f(p, 2, hi[0], hi[1], hi[2]);
  glProgramUniform3f(p, 3, lo[0], lo[1], lo[2]);
  glProgramUniform1f(p, 4, (float)r2);
  glProgramUniform3f(p, 5, (float)d.camera.forward.x, (float)d.camera.forward.y, (float)d.camera.forward.z);
  glProgramUniform3f(p, 6, (float)d.camera.right.x, (float)d.camera.right.y, (float)d.camera.right.z);
  glProgramUniform3f(p, 7, (float)d.camera.up.x, (float)d.camera.up.y, (float)d.camera.up.z);
  glProgramUniform2f(p, 8, (float)(tn * ((double)d.width / d.height)), (float)tn);
  glProgramUniform2i(p, 9, d.width, d.height);
  glProgramUniform3f(p, 10, (float)sun.x, (float)sun.y, (float)sun.z);
  glProgramUniform1f(p, 11, (float)oc_ddot(o, sun));
  glProgramUniform1f(p, 12, (float)cell);
  glProgramUniform1f(p, 13, (float)d.step_factor);
  glProgramUniform1i(p, 14, d.air_steps);
  glProgramUniform1f(p, 15, (float)d.exit_t);
  glProgramUniform1i(p, 16, d.ms_octaves);
  glProgramUniform3f(p, 17, d.ms_a, d.ms_b, d.ms_c);
  glProgramUniform1f(p, 18, d.albedo);
  glProgramUniform3f(p, 19, sun_e.x, sun_e.y, sun_e.z);
  glProgramUniform1ui(p, 20, d.flags);
  glProgramUniform1ui(p, 21, d.frame);
  glProgramUniform1i(p, 22, have_atmo);
  glProgramUniform1f(p, 23, (float)ground_r);
  glProgramUniform1i(p, 24, d.background == OC_BG_CONSTANT);
  glProgramUniform1f(p, 25, d.background_radiance);
  glProgramUniform1f(p, 26, (float)(r2 - ground_r * ground_r));
  glProgramUniform1f(p, 27, (float)(r2 - air_top * air_top));
  glProgramUniform3i(p, 28, gs->atlas_bricks[0], gs->atlas_bricks[1], gs->atlas_bricks[2]);
  glProgramUniform1i(p, 29, d.debug_view);

  glProgramUniform1i(p, 30, phase);
  glProgramUniform1i(p, 31, blend);
  glProgramUniform1f(p, 32, r->t);
  glProgramUniform3i(p, 33, blend ? r->prev->pool_bricks[0] : 1, blend ? r->prev->pool_bricks[1] : 1, 1);
  glProgramUniform1i(p, 34, r->no_map ? 0 : gs->map_level);
  glProgramUniform1ui(p, 35, gs->map_offset);
  glProgramUniform1i(p, 36, d.ms_model);
  int rc = ocv__shadow(r, gs, &d, ground_r, p, ic, fr, why, why_len);
  if (rc < 0) return rc;
  glUseProgram(p);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, gs->tree);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, gs->leaves);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, out);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, depth);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, blend ? r->prev->records : gs->leaves); /* unread when not blending */
  glBindTextureUnit(5, blend ? r->prev->pool : 0);
  glBindBufferBase(GL_UNIFORM_BUFFER, 0, r->atmo_ubo);
  glBindTextureUnit(0, gs->atlas);
  for (int k = 0; k < OC_ATMO_TABLE_COUNT; k++) glBindTextureUnit((GLuint)(1 + k), have_atmo ? r->tab[k] : 0);
  ocv__time_begin(r, 0);
  glDispatchCompute((GLuint)((d.width + OCV__GROUP - 1) / OCV__GROUP), (GLuint)((d.height + OCV__GROUP - 1) / OCV__GROUP), 1);
  ocv__time_end(r, 0);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  glUseProgram(0);
  GLenum err = glGetError();
  if (err != GL_NO_ERROR) {
    (void)oc_errorf(0, why, why_len, "gl render: GL error 0x%x", (unsigned)err);
    return OC_EIO;
  }
  return 0;
}

/* A device buffer of exactly `bytes` (re-created when the size changes). */
static void ocv__buffer(GLuint *b, size_t *have, size_t bytes) {
  if (*b && *have == bytes) return;
  if (*b) glDeleteBuffers(1, b);
  glCreateBuffers(1, b);
  glNamedBufferStorage(*b, (GLsizeiptr)bytes, NULL, GL_DYNAMIC_STORAGE_BIT);
  *have = bytes;
}

int ocv_gl_render_state(ocv_gl_renderer_t *r, const ocv_gl_state_t *gs, const oc_render_desc_t *desc, oc_image_t *img,
                        char *why, size_t why_len) {
  if (!r || !gs || !desc || (img && !img->px)) return ocv__bad(why, why_len, "argument (NULL)");
  if (img && (img->w != desc->width || img->h != desc->height)) return ocv__bad(why, why_len, "size");
  size_t n = (size_t)desc->width * (size_t)desc->height;
  ocv__buffer(&r->out, &r->out_bytes, n * 4 * sizeof(float));
  ocv__buffer(&r->depth, &r->depth_bytes, n * sizeof(float));
  int rc = ocv__dispatch(r, gs, desc, r->out, r->depth, -1, why, why_len);
  if (rc == 0 && img) glGetNamedBufferSubData(r->out, 0, (GLsizeiptr)(n * 4 * sizeof(float)), img->px);
  return rc;
}

GLuint ocv_gl_renderer_output(const ocv_gl_renderer_t *r) { return r ? r->out : 0; }

/*-*** Reprojection: one pixel in 16 traced per frame ***/

/* The order in which the 16 positions of a 4×4 block are traced (a Bayer matrix: consecutive
 * frames are far apart, so a moving camera's errors spread instead of crawling). */
static const int ocv__bayer[16] = {0, 10, 2, 8, 5, 15, 7, 13, 1, 11, 3, 9, 4, 14, 6, 12};
/* the weight of a new jittered sample against its history: about 1/α samples are averaged */
#define OCV__ACCUMULATE 0.2f

struct ocv_gl_history_s {
  int w, h;
  GLuint color[2], depth[2], count[2];              /* ping-pong history (count: samples averaged) */
  GLuint cur, cur_depth, stats;                     /* this frame's traced pixels */
  int newest;                                       /* index of the newest history; -1: none */
  oc_camera_t cam;                                  /* the camera of the newest history */
  uint32_t frame;
  int refresh;                                      /* a new state: history not traced since is clamped */
  uint32_t fresh;                                   /* block positions traced since (bit x | y<<2) */
};

ocv_gl_history_t *ocv_gl_history_create(int w, int h, char *why, size_t why_len) {
  if (w <= 0 || h <= 0 || w > 16384 || h > 16384) {
    (void)oc_errorf(0, why, why_len, "gl history: invalid size %dx%d", w, h);
    return NULL;
  }
  ocv_gl_history_t *hs = calloc(1, sizeof *hs);
  if (!hs) {
    (void)oc_errorf(0, why, why_len, "out of memory");
    return NULL;
  }
  size_t n = (size_t)w * (size_t)h, have = 0; /* each buffer is new: *have is not read */
  hs->w = w;
  hs->h = h;
  hs->newest = -1;
  for (int i = 0; i < 2; i++) {
    ocv__buffer(&hs->color[i], &have, n * 4 * sizeof(float));
    ocv__buffer(&hs->depth[i], &have, n * sizeof(float));
    ocv__buffer(&hs->count[i], &have, n * sizeof(uint32_t));
  }
  ocv__buffer(&hs->cur, &have, n * 4 * sizeof(float));
  ocv__buffer(&hs->cur_depth, &have, n * sizeof(float));
  ocv__buffer(&hs->stats, &have, 2 * sizeof(uint32_t));
  return hs;
}

void ocv_gl_history_free(ocv_gl_history_t *hs) {
  if (!hs) return;
  GLuint b[9] = {hs->color[0], hs->color[1], hs->depth[0], hs->depth[1], hs->count[0], hs->count[1],
                 hs->cur, hs->cur_depth, hs->stats};
  glDeleteBuffers(9, b);
  free(hs);
}

GLuint ocv_gl_history_output(const ocv_gl_history_t *hs) { return hs && hs->newest >= 0 ? hs->color[hs->newest] : 0; }

void ocv_gl_history_reset(ocv_gl_history_t *hs) {
  if (hs) hs->newest = -1;
}

void ocv_gl_history_refresh(ocv_gl_history_t *hs) {
  if (!hs) return;
  hs->refresh = 1; /* until every position of the 4×4 blocks was traced again */
  hs->fresh = 0;
}

int ocv_gl_render_frame(ocv_gl_renderer_t *r, ocv_gl_history_t *hs, const ocv_gl_state_t *gs, const oc_render_desc_t *desc,
                        int reproject, oc_image_t *img, ocv_gl_frame_stats_t *fs, char *why, size_t why_len) {
  if (!r || !hs || !gs || !desc || (img && !img->px)) return ocv__bad(why, why_len, "argument (NULL)");
  if (desc->width != hs->w || desc->height != hs->h || (img && (img->w != hs->w || img->h != hs->h)))
    return ocv__bad(why, why_len, "size (the history's)");
  size_t n = (size_t)hs->w * (size_t)hs->h;
  int next = hs->newest == 0 ? 1 : 0;
  ocv_gl_frame_stats_t st = {0};
  int rc;
  if (!reproject) { /* every pixel traced: the frame is also the next history */
    rc = ocv__dispatch(r, gs, desc, hs->color[next], hs->depth[next], -1, why, why_len);
    glClearNamedBufferData(hs->count[next], GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, NULL); /* no averages yet */
    st.traced = (uint32_t)n;
  } else {
    int phase = ocv__bayer[hs->frame % 16];
    rc = ocv__dispatch(r, gs, desc, hs->cur, hs->cur_depth, phase, why, why_len);
    if (rc == 0) {
      const oc_camera_t *c = &desc->camera, *pc = hs->newest >= 0 ? &hs->cam : c;
      double tn = tan(0.5 * c->vfov_deg * OC_DEG), ptn = tan(0.5 * pc->vfov_deg * OC_DEG), asp = (double)hs->w / hs->h;
      oc_dvec3 dc = oc_dsub(pc->pos, c->pos); /* the previous eye seen from this one: small, exact in double */
      GLuint p = r->reproject;
      glProgramUniform2i(p, 0, hs->w, hs->h);
      glProgramUniform1i(p, 1, phase);
      glProgramUniform1i(p, 2, hs->newest >= 0);
      glProgramUniform3f(p, 3, (float)c->forward.x, (float)c->forward.y, (float)c->forward.z);
      glProgramUniform3f(p, 4, (float)c->right.x, (float)c->right.y, (float)c->right.z);
      glProgramUniform3f(p, 5, (float)c->up.x, (float)c->up.y, (float)c->up.z);
      glProgramUniform2f(p, 6, (float)(tn * asp), (float)tn);
      glProgramUniform3f(p, 7, (float)pc->forward.x, (float)pc->forward.y, (float)pc->forward.z);
      glProgramUniform3f(p, 8, (float)pc->right.x, (float)pc->right.y, (float)pc->right.z);
      glProgramUniform3f(p, 9, (float)pc->up.x, (float)pc->up.y, (float)pc->up.z);
      glProgramUniform2f(p, 10, (float)(ptn * asp), (float)ptn);
      glProgramUniform3f(p, 11, (float)dc.x, (float)dc.y, (float)dc.z);
      /* with jittered ray starts each traced pixel joins its history: the jitter averages out */
      glProgramUniform1f(p, 12, (desc->flags & OC_RF_JITTER) ? OCV__ACCUMULATE : 1.0f);
      int moved = hs->newest >= 0 && (memcmp(&c->pos, &pc->pos, sizeof c->pos) || memcmp(&c->forward, &pc->forward, sizeof c->forward) ||
                                      memcmp(&c->up, &pc->up, sizeof c->up) || c->vfov_deg != pc->vfov_deg);
      glProgramUniform1i(p, 13, moved);
      glProgramUniform1i(p, 14, hs->newest >= 0 && hs->refresh);
      glProgramUniform1ui(p, 15, hs->fresh);
      hs->fresh |= 1u << phase;
      if (hs->fresh == 0xFFFFu) hs->refresh = 0;
      uint32_t zero[2] = {0, 0};
      glNamedBufferSubData(hs->stats, 0, sizeof zero, zero);
      glUseProgram(p);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, hs->cur);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, hs->cur_depth);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, hs->color[hs->newest >= 0 ? hs->newest : next]);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, hs->depth[hs->newest >= 0 ? hs->newest : next]);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, hs->color[next]);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, hs->depth[next]);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, hs->stats);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, hs->count[hs->newest >= 0 ? hs->newest : next]);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 8, hs->count[next]);
      ocv__time_begin(r, 1);
      glDispatchCompute((GLuint)((hs->w + OCV__GROUP - 1) / OCV__GROUP), (GLuint)((hs->h + OCV__GROUP - 1) / OCV__GROUP), 1);
      ocv__time_end(r, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
      glUseProgram(0);
      uint32_t counts[2];
      glGetNamedBufferSubData(hs->stats, 0, sizeof counts, counts);
      st.reprojected = counts[0];
      st.rejected = counts[1];
      st.traced = (uint32_t)(n - counts[0] - counts[1]);
      GLenum err = glGetError();
      if (err != GL_NO_ERROR) rc = oc_errorf(OC_EIO, why, why_len, "gl reproject: GL error 0x%x", (unsigned)err);
    }
  }
  if (rc) return rc;
  if (img) glGetNamedBufferSubData(hs->color[next], 0, (GLsizeiptr)(n * 4 * sizeof(float)), img->px);
  hs->newest = next;
  hs->cam = desc->camera;
  hs->frame++;
  if (!reproject) hs->refresh = 0; /* every pixel traced */
  if (fs) *fs = st;
  return 0;
}
