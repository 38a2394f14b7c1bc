#include "scene_voxelize.h"

#include <math.h>
#include <stdio.h>

#include "oc_err.h"
#include "voxelize.h"

int ocs_scene_medium(const oc_scene_t *sc, ocs_medium_t *m, char *why, size_t why_len) {
  ocs_medium_init(m);
  for (int i = 0; i < sc->nsources; i++) {
    const oc_source_t *src = &sc->sources[i];
    ocs_prim_t p;
    int r;
    switch (src->type) {
      case OC_SOURCE_SPHERE:
        r = ocs_prim_sphere(&p, src->sphere.centre, src->sphere.radius, src->sphere.sigma_t);
        break;
      case OC_SOURCE_BOX:
        r = ocs_prim_box(&p, src->box.base, src->box.size[0], src->box.size[1], src->box.size[2], src->box.heading,
                        src->box.sigma_t);
        break;
      case OC_SOURCE_SLAB:
        r = ocs_prim_slab(&p, src->slab.base, src->slab.top, src->slab.sigma_t);
        break;
      default:
        if (why)
          snprintf(why, why_len, "sources[%d]: a %s source needs overcast-server; local rendering takes analytic sources only",
                   i, oc_scene_source_type_name(src->type));
        return OC_ESCENE;
    }
    if (r == 0) r = ocs_medium_add(m, &p);
    if (r < 0) {
      if (why) snprintf(why, why_len, "sources[%d]: %s", i, oc_strerror(r));
      return OC_ESCENE;
    }
  }
  return 0;
}

typedef struct {
  ocs_medium_ctx_t mc;
  oc_dvec3 eye;
  double k; /**< pixels per (metre / metre): viewport_height / (2 tan(fov/2)) */
  double pixels;
} oc__lod_t;

double ocs_lod_pixels(oc_key_t key, oc_dvec3 eye, double pixels_per_radian) {
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  oc_dvec3 q = oc_dv3(fmax(o.x, fmin(eye.x, o.x + size)), fmax(o.y, fmin(eye.y, o.y + size)),
                      fmax(o.z, fmin(eye.z, o.z + size)));
  return size / 7.0 * pixels_per_radian / fmax(oc_dlen(oc_dsub(q, eye)), 1.0);
}

/* Split while the node's voxel spans more than `pixels` pixels, and only where the medium is. */
static int oc__lod_refine(void *ctx, oc_key_t key) {
  const oc__lod_t *l = ctx;
  if (ocs_lod_pixels(key, l->eye, l->k) <= l->pixels) return 0;
  return ocs_medium_refine_cb((void *)&l->mc, key);
}

int ocs_scene_voxelize(oc_state_t *out, const oc_scene_t *sc, const ocs_scene_voxelize_desc_t *d, char *why,
                      size_t why_len) {
  ocs_medium_t m;
  OC_TRY(ocs_scene_medium(sc, &m, why, why_len));
  int vh = d->viewport_height > 0 ? d->viewport_height : 360;
  oc__lod_t lod = {{&m, sc->sun_dir, 0.0}, d->camera.pos, vh / (2.0 * tan(0.5 * d->camera.vfov_deg * OC_DEG)),
                   d->pixels > 0.0 ? d->pixels : 2.0};
  ocs_voxelize_desc_t vd = {0};
  vd.sigma = ocs_medium_sigma_cb;
  vd.tau = oc_scene_has(sc, OC_FEATURE_SHADOWS) ? ocs_medium_tau_cb : NULL;
  vd.ctx = &lod.mc;
  vd.min_level = 2;
  vd.max_level = d->max_level > 0 ? d->max_level : 16;
  vd.refine = oc__lod_refine;
  vd.refine_ctx = &lod;
  /* τ box-filtered as σt is: then it is the optical depth through the σt channel that the renderer
   * and the truth read (a line integral commutes with the filter). Point-sampled, it is the exact
   * medium's, which lights a voxel straddling a sunlit face as if none of its σt lay above the face
   * (docs/numerics.md, "The reference states' τ"). */
  vd.sub_sigma = vd.sub_tau = OCS_SCENE_VOXELIZE_SUB;
  vd.sun_dir = sc->sun_dir;
  vd.threads = d->threads > 0 ? d->threads : 1;
  vd.max_nodes = d->max_nodes > 0 ? d->max_nodes : 500000;
  int r = ocs_voxelize(out, &vd);
  if (r < 0 && why)
    snprintf(why, why_len, "voxelizing the scene: %s%s", oc_strerror(r),
             r == OC_ETOOBIG ? " (a lower max_level or a higher max_nodes)" : "");
  return r;
}
