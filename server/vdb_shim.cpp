// vdb_shim.cpp — the OpenVDB shim: the project's only C++ file (C++17), behind the plain C table
// of vdb_shim.h. Built as liboc_vdb_shim.so and opened with dlopen only when VDB is used.
//
// Boundary rules (style.md, habit 4): this is the one file that sees OpenVDB. Every table entry
// catches every exception and turns it into a negative OC_E* plus a one-line reason; no C++ type
// crosses the table. Reading goes through OpenVDB's own io::Stream (half floats, zip, blosc,
// constant tiles at every tree level are OpenVDB's business, not ours) fed by a counting
// std::streambuf that reports progress to a C callback and lets us tell a truncated file from a
// complete one (OpenVDB 10 silently returns partial grids when the stream ends early: the stream
// is set to throw on failbit, so the first short read aborts the read).
//
// Sampling structure (docs/vdb.md, "Filtering"): a prepared grid holds a sparse pyramid.
// Level 0 is the file's tree itself (sanitised, inactive values and background 0); level l cell
// a is the mean of the 2^l-cubed voxels 2^l·a + [0, 2^l)^3, built level by level from 2×2×2
// means, so every level holds the same total mass. Two more trees per level hold the min and max
// over the same voxels (inactive voxels count as 0): grid_range answers conservative bounds from
// a handful of cells.
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/points/PointConversion.h>
#include <openvdb/points/PointCount.h>
#include <openvdb/points/PointDataGrid.h>

#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <istream>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <vector>

#include "oc_err.h"
#include "vdb_shim.h"

namespace {

using openvdb::Coord;
using openvdb::CoordBBox;
using openvdb::FloatGrid;
using openvdb::FloatTree;


void set_why(char *why, size_t len, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
void set_why(char *why, size_t len, const char *fmt, ...) {
  if (!why || !len) return;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(why, len, fmt, ap);
  va_end(ap);
}

// Called in a catch block: the exception in flight as the reason "<context>: <its what()>"
// ("<context>: unknown error" for one that is not a std::exception). @return err.
int caught(int err, char *why, size_t len, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
int caught(int err, char *why, size_t len, const char *fmt, ...) {
  char context[4096];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(context, sizeof context, fmt, ap);
  va_end(ap);
  try {
    throw;
  } catch (const std::exception &e) {
    set_why(why, len, "%s: %s", context, e.what());
  } catch (...) {
    set_why(why, len, "%s: unknown error", context);
  }
  return err;
}

// ---- Reading with progress ------------------------------------------------------------------------

// A read-only streambuf over a FILE* with a 1 MiB buffer. It counts the bytes handed out (for the
// progress callback) and remembers whether the file ended while OpenVDB still wanted data.
class CountingBuf : public std::streambuf {
 public:
  CountingBuf(FILE *fp, uint64_t total, ocs_vdb_progress_fn fn, void *ctx)
      : fp_(fp), total_(total), fn_(fn), ctx_(ctx), buf_(1u << 20) {
    setg(buf_.data(), buf_.data(), buf_.data());
  }
  uint64_t position() const { return base_ + (uint64_t)(gptr() - eback()); }
  bool hit_eof() const { return eof_; }

 protected:
  int_type underflow() override {
    if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
    base_ += (uint64_t)(egptr() - eback());
    size_t n = fread(buf_.data(), 1, buf_.size(), fp_);
    setg(buf_.data(), buf_.data(), buf_.data() + n);
    if (fn_) fn_(ctx_, base_ + n, total_); // bytes read from the file so far
    if (n == 0) {
      eof_ = true;
      return traits_type::eof();
    }
    return traits_type::to_int_type(*gptr());
  }
  pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override {
    int64_t target = dir == std::ios_base::beg   ? (int64_t)off
                     : dir == std::ios_base::cur ? (int64_t)position() + off
                                                 : (int64_t)total_ + off;
    return seekpos(pos_type(target), std::ios_base::in);
  }
  pos_type seekpos(pos_type pos, std::ios_base::openmode) override {
    int64_t target = (int64_t)pos;
    if (target < 0 || (uint64_t)target > total_) return pos_type(off_type(-1));
    if ((uint64_t)target == position()) return pos;
    if (fseeko(fp_, (off_t)target, SEEK_SET) != 0) return pos_type(off_type(-1));
    base_ = (uint64_t)target;
    setg(buf_.data(), buf_.data(), buf_.data());
    return pos;
  }

 private:
  FILE *fp_;
  uint64_t total_, base_ = 0;
  ocs_vdb_progress_fn fn_;
  void *ctx_;
  std::vector<char> buf_;
  bool eof_ = false;
};

}  // namespace

struct ocs_vdb_file_s {
  openvdb::GridPtrVec grids;
  uint64_t bytes = 0;
  uint32_t compression = 0, version = 0;
};

// Pyramid levels ≥ 1 use a small-fanout tree (8³ children per internal node, 4 KiB each):
// OpenVDB's 5-4-3 float tree spends ~270 KiB per upper internal node, and a grid that straddles
// the index origin keeps up to 8 of them per tree at every level.
using PyrTree = openvdb::tree::Tree4<float, 3, 3, 3>::Type;

struct ocs_vdb_grid_s {
  int levels = 0;
  FloatTree::Ptr base;                           // level 0: the file's tree, sanitised
  std::vector<PyrTree::Ptr> mean, vmin, vmax;    // level l ≥ 1 at [l - 1]
  std::vector<CoordBBox> bbox;                   // active bbox of each level (cells)
};

struct ocs_vdb_writer_s {
  struct Entry {
    openvdb::GridBase::Ptr grid;
    int type;
    double bad_voxel_size; // the value to patch in (when patch is set)
    bool patch;
  };
  std::vector<Entry> grids;
};

namespace {

// Floor division by 2^s for int32 (gcc's >> on negative ints is arithmetic: floor).
inline int32_t fshift(int32_t a, int s) { return a >> s; }
inline Coord cshift(const Coord &c, int s) { return Coord(fshift(c.x(), s), fshift(c.y(), s), fshift(c.z(), s)); }

int type_of(const openvdb::GridBase &g) {
  const std::string t = g.valueType();
  if (g.isType<openvdb::points::PointDataGrid>() || t.rfind("ptdataidx", 0) == 0) return OCS_VDB_TYPE_POINTS;
  if (t == "float") return OCS_VDB_TYPE_FLOAT;
  if (t == "double") return OCS_VDB_TYPE_DOUBLE;
  if (t == "int32") return OCS_VDB_TYPE_INT32;
  if (t == "int64") return OCS_VDB_TYPE_INT64;
  if (t == "vec3s" || t == "vec3d" || t == "vec3i") return OCS_VDB_TYPE_VEC3;
  return OCS_VDB_TYPE_OTHER;
}

template <typename V> double scalar_of(const V &v) { return (double)v; }
template <typename T> double scalar_of(const openvdb::math::Vec3<T> &v) { return v.length(); }

// Range of the finite active values and counts of the others (a tile counts once).
template <typename GridT> void scan_range(const openvdb::GridBase &base, ocs_vdb_grid_info_t *out) {
  const GridT &g = static_cast<const GridT &>(base);
  double lo = INFINITY, hi = -INFINITY;
  for (auto it = g.tree().cbeginValueOn(); it; ++it) {
    double v = scalar_of(*it);
    if (std::isnan(v)) {
      out->nan++;
    } else if (std::isinf(v)) {
      out->inf++;
    } else {
      if (v < 0) out->negative++;
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  out->has_range = 1;
  out->vmin = lo <= hi ? lo : 0.0;
  out->vmax = lo <= hi ? hi : 0.0;
}

void fill_info(const openvdb::GridBase &g, int with_range, ocs_vdb_grid_info_t *out) {
  memset(out, 0, sizeof *out);
  snprintf(out->name, sizeof out->name, "%s", g.getName().c_str());
  snprintf(out->value_type, sizeof out->value_type, "%s", g.valueType().c_str());
  out->type = type_of(g);
  out->klass = (int)g.getGridClass();
  out->half = g.saveFloatAsHalf() ? 1 : 0;
  const openvdb::math::Transform &xf = g.transform();
  out->linear = xf.isLinear() ? 1 : 0;
  openvdb::Vec3d vs = xf.voxelSize();
  for (int a = 0; a < 3; a++) out->voxel_size[a] = vs[a];
  if (out->linear) {
    openvdb::Vec3d t = xf.indexToWorld(openvdb::Vec3d(0, 0, 0));
    for (int c = 0; c < 3; c++) {
      openvdb::Vec3d e(0, 0, 0);
      e[c] = 1.0;
      openvdb::Vec3d col = xf.indexToWorld(e) - t;
      for (int r = 0; r < 3; r++) out->i2w[r][c] = col[r];
    }
    for (int r = 0; r < 3; r++) out->i2w[r][3] = t[r];
  }
  out->active_voxels = g.activeVoxelCount();
  out->leaf_nodes = g.baseTree().leafCount();
  out->active_tiles = g.baseTree().activeTileCount();
  CoordBBox b = g.evalActiveVoxelBoundingBox();
  for (int a = 0; a < 3; a++) {
    out->bbox_min[a] = b.min()[a];
    out->bbox_max[a] = b.max()[a];
  }
  if (out->type == OCS_VDB_TYPE_POINTS && g.isType<openvdb::points::PointDataGrid>())
    out->points = openvdb::points::pointCount(static_cast<const openvdb::points::PointDataGrid &>(g).tree());
  if (!with_range) return;
  if (g.isType<FloatGrid>()) scan_range<FloatGrid>(g, out);
  else if (g.isType<openvdb::DoubleGrid>()) scan_range<openvdb::DoubleGrid>(g, out);
  else if (g.isType<openvdb::Int32Grid>()) scan_range<openvdb::Int32Grid>(g, out);
  else if (g.isType<openvdb::Int64Grid>()) scan_range<openvdb::Int64Grid>(g, out);
  else if (g.isType<openvdb::Vec3SGrid>()) scan_range<openvdb::Vec3SGrid>(g, out);
  else if (g.isType<openvdb::Vec3DGrid>()) scan_range<openvdb::Vec3DGrid>(g, out);
  else if (g.isType<openvdb::Vec3IGrid>()) scan_range<openvdb::Vec3IGrid>(g, out);
}

// ---- Table entries: reading -----------------------------------------------------------------------

const char *shim_version() {
  static std::string v;
  static std::once_flag once;
  std::call_once(once, [] {
    v = std::string("OpenVDB ") + openvdb::getLibraryVersionString() + " (ABI " +
        std::to_string(OPENVDB_ABI_VERSION_NUMBER) + (openvdb::io::Archive::hasBloscCompression() ? ", blosc)" : ", no blosc)");
  });
  return v.c_str();
}

int shim_open(const char *path, ocs_vdb_progress_fn progress, void *ctx, ocs_vdb_file_t **out, char *why, size_t why_len) {
  if (!out) return OC_EINVAL;
  *out = nullptr;
  if (!path) return OC_EINVAL;
  struct stat st;
  if (stat(path, &st) != 0) {
    int e = errno;
    set_why(why, why_len, "%s", e == ENOENT ? "no such file" : strerror(e));
    return e == ENOENT ? OC_ENOENT : OC_EIO;
  }
  if (S_ISDIR(st.st_mode)) {
    set_why(why, why_len, "is a directory, not a VDB file");
    return OC_EIO;
  }
  FILE *fp = fopen(path, "rb");
  if (!fp) {
    set_why(why, why_len, "cannot open: %s", strerror(errno));
    return OC_EIO;
  }
  // The magic number first: OpenVDB's own message for a short file would be "truncated".
  unsigned char magic[8];
  size_t got = fread(magic, 1, sizeof magic, fp);
  static const unsigned char vdb_magic[8] = {0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0}; // int64 0x56444220
  if (got < sizeof magic || memcmp(magic, vdb_magic, sizeof magic) != 0) {
    fclose(fp);
    set_why(why, why_len, got == 0 ? "not a VDB file (empty)" : "not a VDB file (no OpenVDB magic number at the start)");
    return OC_EVERSION;
  }
  rewind(fp);
  uint64_t total = (uint64_t)st.st_size;
  int rc = 0;
  CountingBuf buf(fp, total, progress, ctx);
  std::istream is(&buf);
  std::unique_ptr<ocs_vdb_file_s> f;
  try {
    is.exceptions(std::ios::failbit | std::ios::badbit);
    f.reset(new ocs_vdb_file_s);
    openvdb::io::Stream stream(is, /*delayLoad=*/false);
    openvdb::GridPtrVecPtr grids = stream.getGrids();
    if (grids) f->grids = *grids;
    f->bytes = total;
    f->compression = stream.compression();
    f->version = stream.fileVersion(); // trailing bytes after the last grid are legal
  } catch (const std::ios_base::failure &) {
    set_why(why, why_len, "truncated: the data ends early (OpenVDB wanted more after %llu of %llu bytes)",
            (unsigned long long)buf.position(), (unsigned long long)total);
    rc = OC_ETRUNC;
  } catch (const std::bad_alloc &) {
    set_why(why, why_len, "out of memory while reading (corrupt sizes?)");
    rc = OC_ENOMEM;
  } catch (const openvdb::IoError &e) {
    set_why(why, why_len, "OpenVDB cannot read it: %s", e.what());
    rc = strstr(e.what(), "not a VDB") || strstr(e.what(), "version") ? OC_EVERSION : OC_ECORRUPT;
  } catch (const std::exception &e) {
    set_why(why, why_len, "%s: %s", buf.hit_eof() ? "truncated or corrupt" : "corrupt", e.what());
    rc = buf.hit_eof() ? OC_ETRUNC : OC_ECORRUPT;
  } catch (...) {
    set_why(why, why_len, "corrupt: unknown error while reading");
    rc = OC_ECORRUPT;
  }
  fclose(fp);
  if (rc == 0 && buf.hit_eof()) {
    set_why(why, why_len, "truncated: the data ends early (%llu bytes)", (unsigned long long)total);
    rc = OC_ETRUNC;
  }
  if (rc == 0) *out = f.release();
  return rc;
}

void shim_close(ocs_vdb_file_t *f) {
  try {
    delete f;
  } catch (...) {
  }
}

void shim_file_info(const ocs_vdb_file_t *f, uint64_t *bytes, uint32_t *compression, uint32_t *version) {
  if (bytes) *bytes = f ? f->bytes : 0;
  if (compression) *compression = f ? f->compression : 0;
  if (version) *version = f ? f->version : 0;
}

int shim_grid_count(const ocs_vdb_file_t *f) { return f ? (int)f->grids.size() : 0; }

int shim_grid_info(const ocs_vdb_file_t *f, int i, int with_range, ocs_vdb_grid_info_t *out) {
  if (!f || !out || i < 0 || (size_t)i >= f->grids.size() || !f->grids[(size_t)i]) return OC_EINVAL;
  try {
    fill_info(*f->grids[(size_t)i], with_range, out);
    return 0;
  } catch (const std::bad_alloc &) {
    return OC_ENOMEM;
  } catch (...) {
    return OC_ECORRUPT;
  }
}

// ---- Preparing a grid -----------------------------------------------------------------------------

// Sanitises the active values in place (NaN, ±Inf, negatives → 0; a tile counts its voxels) and
// makes every inactive value and the background 0, so "inactive" means "no medium".
void sanitise(FloatTree &tree, ocs_vdb_prep_stats_t *st) {
  for (auto it = tree.beginValueOn(); it; ++it) {
    float v = *it;
    if (std::isfinite(v) && v >= 0.0f) continue;
    uint64_t n = it.isVoxelValue() ? 1 : it.getBoundingBox().volume();
    if (std::isnan(v)) st->nan += n;
    else if (std::isinf(v)) st->inf += n;
    else st->negative += n;
    it.setValue(0.0f);
  }
  tree.root().setBackground(0.0f, /*updateChildNodes=*/true);
  for (auto it = tree.beginValueOff(); it; ++it)
    if (*it != 0.0f) it.setValue(0.0f);
}

// Builds level l + 1 (mean, min, max) from level l's trees. Tiles of the finer level (edges ≥ 8,
// aligned) map to whole coarse boxes of the same value; every other coarse cell is computed from
// its 8 children (inactive children read 0).
template <typename FineT>
void build_level(ocs_vdb_grid_s &g, const FineT &fm, const FineT &fn, const FineT &fx) {
  PyrTree::Ptr cm(new PyrTree(0.0f)), cn(new PyrTree(0.0f)), cx(new PyrTree(0.0f));
  openvdb::MaskTree topo(false);
  {
    openvdb::tree::ValueAccessor<openvdb::MaskTree> ta(topo);
    for (auto it = fm.cbeginValueOn(); it; ++it) {
      if (it.isVoxelValue()) {
        ta.setValueOn(cshift(it.getCoord(), 1));
        continue;
      }
      CoordBBox b = it.getBoundingBox();
      CoordBBox cb(cshift(b.min(), 1), cshift(b.max(), 1));
      cm->sparseFill(cb, *it, true);
      cn->sparseFill(cb, fn.getValue(b.min()), true);
      cx->sparseFill(cb, fx.getValue(b.min()), true);
    }
  }
  openvdb::tree::ValueAccessor<const FineT, false> am(fm), an(fn), ax(fx);
  openvdb::tree::ValueAccessor<PyrTree> wm(*cm), wn(*cn), wx(*cx);
  for (auto leaf = topo.cbeginLeaf(); leaf; ++leaf) {
    for (auto v = leaf->cbeginValueOn(); v; ++v) {
      const Coord c = v.getCoord(), b(c.x() * 2, c.y() * 2, c.z() * 2);
      double sum = 0.0;
      float lo = INFINITY, hi = -INFINITY;
      for (int k = 0; k < 8; k++) {
        const Coord q = b.offsetBy(k & 1, (k >> 1) & 1, (k >> 2) & 1);
        sum += am.getValue(q);
        lo = std::min(lo, an.getValue(q));
        hi = std::max(hi, ax.getValue(q));
      }
      wm.setValueOn(c, (float)(sum / 8.0));
      wn.setValueOn(c, lo);
      wx.setValueOn(c, hi);
    }
  }
  g.mean.push_back(cm);
  g.vmin.push_back(cn);
  g.vmax.push_back(cx);
  const CoordBBox &fb = g.bbox.back();
  g.bbox.push_back(fb.empty() ? fb : CoordBBox(cshift(fb.min(), 1), cshift(fb.max(), 1)));
}

template <typename GridT> FloatTree::Ptr to_float_tree(openvdb::GridBase::Ptr base) {
  auto g = openvdb::gridPtrCast<GridT>(base);
  if constexpr (std::is_same<GridT, FloatGrid>::value) {
    return g->treePtr();
  } else {
    return FloatTree::Ptr(new FloatTree(g->tree())); // value-converting deep copy
  }
}

int shim_grid_prepare(ocs_vdb_file_t *f, int i, ocs_vdb_grid_t **out, ocs_vdb_prep_stats_t *st, char *why, size_t why_len) {
  if (!out) return OC_EINVAL;
  *out = nullptr;
  ocs_vdb_prep_stats_t dummy;
  if (!st) st = &dummy;
  memset(st, 0, sizeof *st);
  if (!f || i < 0 || (size_t)i >= f->grids.size() || !f->grids[(size_t)i]) {
    set_why(why, why_len, "no grid %d", i);
    return OC_EINVAL;
  }
  auto t0 = std::chrono::steady_clock::now();
  try {
    openvdb::GridBase::Ptr base = f->grids[(size_t)i];
    FloatTree::Ptr tree;
    if (base->isType<FloatGrid>()) tree = to_float_tree<FloatGrid>(base);
    else if (base->isType<openvdb::DoubleGrid>()) tree = to_float_tree<openvdb::DoubleGrid>(base);
    else {
      set_why(why, why_len, "grid %d ('%s') has value type %s, not float", i, base->getName().c_str(), base->valueType().c_str());
      return OC_EINVAL;
    }
    f->grids[(size_t)i].reset(); // the file no longer owns it: one copy in memory
    std::unique_ptr<ocs_vdb_grid_s> g(new ocs_vdb_grid_s);
    sanitise(*tree, st);
    CoordBBox b;
    tree->evalActiveVoxelBoundingBox(b);
    g->base = tree;
    g->bbox.push_back(b);
    uint64_t bytes = tree->memUsage();
    // Coarsen to OCS_VDB_MAX_LEVELS: levels past the point where the grid fits in one cell cost
    // a few cells each, and keep samples far larger than the grid from aliasing it.
    for (int l = 1; l < OCS_VDB_MAX_LEVELS && !b.empty(); l++) {
      if (l == 1) build_level(*g, *tree, *tree, *tree);
      else build_level(*g, *g->mean.back(), *g->vmin.back(), *g->vmax.back());
      bytes += g->mean.back()->memUsage() + g->vmin.back()->memUsage() + g->vmax.back()->memUsage();
    }
    g->levels = 1 + (int)g->mean.size();
    st->levels = g->levels;
    st->bytes = bytes;
    st->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    *out = g.release();
    return 0;
  } catch (const std::bad_alloc &) {
    set_why(why, why_len, "out of memory preparing grid %d", i);
    return OC_ENOMEM;
  } catch (...) {
    return caught(OC_ECORRUPT, why, why_len, "preparing grid %d", i);
  }
}

void shim_grid_free(ocs_vdb_grid_t *g) {
  try {
    delete g;
  } catch (...) {
  }
}

int shim_grid_levels(const ocs_vdb_grid_t *g) { return g ? g->levels : 0; }

// Trilinear interpolation of one level's means (TreeT: level 0's or the pyramid's tree type; both
// have 8³ leaves). Never throws: getValue on a const tree only reads.
template <typename TreeT> void sample_tree(const TreeT &tree, int level, const double *xyz, size_t n, float *out) {
  openvdb::tree::ValueAccessor<const TreeT, false> acc(tree);
  const double inv = std::ldexp(1.0, -level);
  for (size_t i = 0; i < n; i++) {
    int32_t c[3];
    double t[3];
    for (int a = 0; a < 3; a++) {
      double x = (xyz[3 * i + (size_t)a] + 0.5) * inv - 0.5;
      x = x < -1e9 ? -1e9 : x > 1e9 ? 1e9 : x; // far points: stay inside int32, read background
      double fl = std::floor(x);
      c[a] = (int32_t)fl;
      t[a] = x - fl;
    }
    double v[8];
    if ((c[0] & 7) != 7 && (c[1] & 7) != 7 && (c[2] & 7) != 7) {
      // The 2×2×2 corners lie in one leaf (or one tile, or empty space): read them directly.
      const Coord q(c[0], c[1], c[2]);
      const typename TreeT::LeafNodeType *leaf = acc.probeConstLeaf(q);
      if (leaf) {
        const float *buf = leaf->buffer().data();
        const int o = ((c[0] & 7) << 6) | ((c[1] & 7) << 3) | (c[2] & 7); // x slowest in a leaf
        v[0] = buf[o], v[1] = buf[o + 64], v[2] = buf[o + 8], v[3] = buf[o + 72];
        v[4] = buf[o + 1], v[5] = buf[o + 65], v[6] = buf[o + 9], v[7] = buf[o + 73];
      } else {
        const double tile = acc.getValue(q);
        for (int k = 0; k < 8; k++) v[k] = tile;
      }
    } else {
      for (int k = 0; k < 8; k++) v[k] = acc.getValue(Coord(c[0] + (k & 1), c[1] + ((k >> 1) & 1), c[2] + ((k >> 2) & 1)));
    }
    double x00 = v[0] + (v[1] - v[0]) * t[0], x10 = v[2] + (v[3] - v[2]) * t[0];
    double x01 = v[4] + (v[5] - v[4]) * t[0], x11 = v[6] + (v[7] - v[6]) * t[0];
    double y0 = x00 + (x10 - x00) * t[1], y1 = x01 + (x11 - x01) * t[1];
    out[i] = (float)(y0 + (y1 - y0) * t[2]);
  }
}

void shim_grid_sample(const ocs_vdb_grid_t *g, int level, const double *xyz, size_t n, float *out) {
  if (!g || g->levels < 1) {
    for (size_t i = 0; i < n; i++) out[i] = 0.0f;
    return;
  }
  level = level < 0 ? 0 : level >= g->levels ? g->levels - 1 : level;
  if (level == 0) sample_tree(*g->base, 0, xyz, n, out);
  else sample_tree(*g->mean[(size_t)level - 1], level, xyz, n, out);
}

template <typename TreeT>
void range_tree(const TreeT &tmin, const TreeT &tmax, const CoordBBox &cq, float *mn, float *mx) {
  openvdb::tree::ValueAccessor<const TreeT, false> an(tmin), ax(tmax);
  for (int32_t z = cq.min().z(); z <= cq.max().z(); z++)
    for (int32_t y = cq.min().y(); y <= cq.max().y(); y++)
      for (int32_t x = cq.min().x(); x <= cq.max().x(); x++) {
        Coord c(x, y, z);
        *mn = std::min(*mn, an.getValue(c));
        *mx = std::max(*mx, ax.getValue(c));
      }
}

void shim_grid_range(const ocs_vdb_grid_t *g, const int32_t lo[3], const int32_t hi[3], float *vmin, float *vmax) {
  *vmin = 0.0f;
  *vmax = 0.0f;
  if (!g || g->levels < 1 || g->bbox[0].empty()) return;
  CoordBBox q(Coord(lo[0], lo[1], lo[2]), Coord(hi[0], hi[1], hi[2]));
  if (q.empty() || !q.hasOverlap(g->bbox[0])) return;
  bool outside = !g->bbox[0].isInside(q); // part of the box is empty space: min is 0
  int32_t ext = std::max(q.dim().x(), std::max(q.dim().y(), q.dim().z()));
  int l = 0;
  while (l < g->levels - 1 && (ext >> l) > 4) l++;
  CoordBBox cq(cshift(q.min(), l), cshift(q.max(), l));
  cq.intersect(g->bbox[(size_t)l]);
  float mn = INFINITY, mx = 0.0f;
  if (l == 0) range_tree(*g->base, *g->base, cq, &mn, &mx);
  else range_tree(*g->vmin[(size_t)l - 1], *g->vmax[(size_t)l - 1], cq, &mn, &mx);
  *vmin = outside || !(mn <= mx) ? 0.0f : mn;
  *vmax = mx;
}

// ---- Writing --------------------------------------------------------------------------------------

int shim_writer_create(ocs_vdb_writer_t **out) {
  if (!out) return OC_EINVAL;
  *out = new (std::nothrow) ocs_vdb_writer_s;
  return *out ? 0 : OC_ENOMEM;
}

void shim_writer_free(ocs_vdb_writer_t *w) {
  try {
    delete w;
  } catch (...) {
  }
}

// A placeholder voxel size per grid: OpenVDB refuses to build a zero-scale transform, so a grid
// asked to carry a bad one is written with this and the bytes are patched after saving.
double placeholder_voxel_size(size_t grid) { return 0.123456789012345 + 1e-9 * (double)grid; }

int shim_writer_add_grid(ocs_vdb_writer_t *w, const ocs_vdb_grid_desc_t *d, char *why, size_t why_len) {
  if (!w || !d || !d->name || !d->name[0] || strlen(d->name) > 127) {
    set_why(why, why_len, "a grid needs a name of 1 to 127 bytes");
    return OC_EINVAL;
  }
  try {
    ocs_vdb_writer_s::Entry e;
    e.type = d->type ? d->type : OCS_VDB_TYPE_FLOAT;
    e.patch = false;
    e.bad_voxel_size = 0.0;
    openvdb::math::Transform::Ptr xf;
    if (d->affine) {
      openvdb::Mat4d m = openvdb::Mat4d::identity();
      for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) m(c, r) = d->i2w[r][c]; // OpenVDB multiplies row vectors
        m(3, r) = d->i2w[r][3];
      }
      xf = openvdb::math::Transform::createLinearTransform(m);
    } else if (std::isfinite(d->voxel_size) && d->voxel_size > 0.0) {
      xf = openvdb::math::Transform::createLinearTransform(d->voxel_size);
    } else {
      e.patch = true;
      e.bad_voxel_size = d->voxel_size;
      xf = openvdb::math::Transform::createLinearTransform(placeholder_voxel_size(w->grids.size()));
    }
    switch (e.type) {
      case OCS_VDB_TYPE_FLOAT: e.grid = FloatGrid::create(0.0f); break;
      case OCS_VDB_TYPE_DOUBLE: e.grid = openvdb::DoubleGrid::create(0.0); break;
      case OCS_VDB_TYPE_INT32: e.grid = openvdb::Int32Grid::create(0); break;
      case OCS_VDB_TYPE_VEC3: e.grid = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f)); break;
      case OCS_VDB_TYPE_POINTS: e.grid = openvdb::points::PointDataGrid::create(); break;
      default: set_why(why, why_len, "grid '%s': type %d cannot be written", d->name, d->type); return OC_EINVAL;
    }
    e.grid->setName(d->name);
    e.grid->setTransform(xf);
    e.grid->setGridClass((openvdb::GridClass)(d->klass >= 0 && d->klass <= 3 ? d->klass : 0));
    if (d->half) e.grid->setSaveFloatAsHalf(true);
    w->grids.push_back(e);
    return (int)w->grids.size() - 1;
  } catch (...) {
    return caught(OC_EINVAL, why, why_len, "grid '%s'", d->name);
  }
}

template <typename GridT, typename F> void set_block(openvdb::GridBase &base, const int32_t o[3], const int32_t d[3], const float *v, F conv) {
  GridT &g = static_cast<GridT &>(base);
  auto acc = g.getAccessor();
  size_t i = 0;
  for (int32_t z = 0; z < d[2]; z++)
    for (int32_t y = 0; y < d[1]; y++)
      for (int32_t x = 0; x < d[0]; x++, i++)
        if (v[i] != 0.0f || std::isnan(v[i])) acc.setValueOn(Coord(o[0] + x, o[1] + y, o[2] + z), conv(v[i]));
}

int shim_writer_set_values(ocs_vdb_writer_t *w, int grid, const int32_t origin[3], const int32_t dims[3], const float *values) {
  if (!w || grid < 0 || (size_t)grid >= w->grids.size() || !origin || !dims || !values) return OC_EINVAL;
  if (dims[0] < 0 || dims[1] < 0 || dims[2] < 0) return OC_EINVAL;
  try {
    ocs_vdb_writer_s::Entry &e = w->grids[(size_t)grid];
    switch (e.type) {
      case OCS_VDB_TYPE_FLOAT: set_block<FloatGrid>(*e.grid, origin, dims, values, [](float v) { return v; }); break;
      case OCS_VDB_TYPE_DOUBLE: set_block<openvdb::DoubleGrid>(*e.grid, origin, dims, values, [](float v) { return (double)v; }); break;
      case OCS_VDB_TYPE_INT32: set_block<openvdb::Int32Grid>(*e.grid, origin, dims, values, [](float v) { return (int32_t)std::lround(v); }); break;
      case OCS_VDB_TYPE_VEC3:
        set_block<openvdb::Vec3SGrid>(*e.grid, origin, dims, values, [](float v) { return openvdb::Vec3s(v, 0.0f, 0.0f); });
        break;
      default: return OC_EINVAL;
    }
    return 0;
  } catch (const std::bad_alloc &) {
    return OC_ENOMEM;
  } catch (...) {
    return OC_EINVAL;
  }
}

int shim_writer_fill(ocs_vdb_writer_t *w, int grid, const int32_t lo[3], const int32_t hi[3], float value) {
  if (!w || grid < 0 || (size_t)grid >= w->grids.size() || !lo || !hi) return OC_EINVAL;
  try {
    ocs_vdb_writer_s::Entry &e = w->grids[(size_t)grid];
    CoordBBox b(Coord(lo[0], lo[1], lo[2]), Coord(hi[0], hi[1], hi[2]));
    if (e.type == OCS_VDB_TYPE_FLOAT) openvdb::gridPtrCast<FloatGrid>(e.grid)->sparseFill(b, value, true);
    else if (e.type == OCS_VDB_TYPE_DOUBLE) openvdb::gridPtrCast<openvdb::DoubleGrid>(e.grid)->sparseFill(b, (double)value, true);
    else return OC_EINVAL;
    return 0;
  } catch (const std::bad_alloc &) {
    return OC_ENOMEM;
  } catch (...) {
    return OC_EINVAL;
  }
}

int shim_writer_add_points(ocs_vdb_writer_t *w, int grid, const double *xyz, size_t n) {
  if (!w || grid < 0 || (size_t)grid >= w->grids.size() || (!xyz && n)) return OC_EINVAL;
  try {
    ocs_vdb_writer_s::Entry &e = w->grids[(size_t)grid];
    if (e.type != OCS_VDB_TYPE_POINTS) return OC_EINVAL;
    std::vector<openvdb::Vec3R> pos(n);
    for (size_t i = 0; i < n; i++) pos[i] = openvdb::Vec3R(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    auto pg = openvdb::points::createPointDataGrid<openvdb::points::NullCodec, openvdb::points::PointDataGrid>(
        pos, e.grid->transform());
    pg->setName(e.grid->getName());
    pg->setGridClass(e.grid->getGridClass());
    e.grid = pg;
    return 0;
  } catch (const std::bad_alloc &) {
    return OC_ENOMEM;
  } catch (...) {
    return OC_EINVAL;
  }
}

int shim_writer_set_meta(ocs_vdb_writer_t *w, int grid, const char *key, double value, const char *str) {
  if (!w || grid < 0 || (size_t)grid >= w->grids.size() || !key || !key[0]) return OC_EINVAL;
  try {
    openvdb::GridBase &g = *w->grids[(size_t)grid].grid;
    g.removeMeta(key);
    if (str) g.insertMeta(key, openvdb::StringMetadata(str));
    else g.insertMeta(key, openvdb::DoubleMetadata(value));
    return 0;
  } catch (...) {
    return OC_EINVAL;
  }
}

// Replaces every 8-byte occurrence of `from` with `to` in the file (bad voxel sizes for tests).
int patch_doubles(const char *path, double from, double to) {
  FILE *fp = fopen(path, "r+b");
  if (!fp) return OC_EIO;
  std::vector<unsigned char> data;
  unsigned char chunk[65536];
  size_t n;
  while ((n = fread(chunk, 1, sizeof chunk, fp)) > 0) data.insert(data.end(), chunk, chunk + n);
  unsigned char a[8], b[8];
  memcpy(a, &from, 8);
  memcpy(b, &to, 8);
  int count = 0;
  for (size_t i = 0; i + 8 <= data.size(); i++)
    if (memcmp(&data[i], a, 8) == 0) {
      memcpy(&data[i], b, 8);
      count++;
      i += 7;
    }
  rewind(fp);
  bool ok = fwrite(data.data(), 1, data.size(), fp) == data.size();
  ok = fclose(fp) == 0 && ok;
  return ok && count > 0 ? 0 : OC_EIO;
}

int shim_writer_save(ocs_vdb_writer_t *w, const char *path, int compression, char *why, size_t why_len) {
  if (!w || !path) return OC_EINVAL;
  uint32_t flags;
  bool blosc = openvdb::io::Archive::hasBloscCompression();
  switch (compression) {
    case OCS_VDB_COMPRESS_DEFAULT: flags = (blosc ? openvdb::io::COMPRESS_BLOSC : openvdb::io::COMPRESS_ZIP) | openvdb::io::COMPRESS_ACTIVE_MASK; break;
    case OCS_VDB_COMPRESS_NONE: flags = openvdb::io::COMPRESS_NONE; break;
    case OCS_VDB_COMPRESS_ZIP: flags = openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK; break;
    case OCS_VDB_COMPRESS_BLOSC:
      if (!blosc) {
        set_why(why, why_len, "this OpenVDB has no blosc compression");
        return OC_EINVAL;
      }
      flags = openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK;
      break;
    default: set_why(why, why_len, "unknown compression %d", compression); return OC_EINVAL;
  }
  try {
    openvdb::GridCPtrVec grids;
    for (auto &e : w->grids) grids.push_back(e.grid);
    openvdb::io::File file(path);
    file.setCompression(flags);
    file.write(grids);
    file.close();
  } catch (...) {
    return caught(OC_EIO, why, why_len, "cannot write %s", path);
  }
  for (size_t i = 0; i < w->grids.size(); i++)
    if (w->grids[i].patch && patch_doubles(path, placeholder_voxel_size(i), w->grids[i].bad_voxel_size) < 0) {
      set_why(why, why_len, "cannot patch the voxel size of grid %zu in %s", i, path);
      return OC_EIO;
    }
  return 0;
}

const ocs_vdb_api_t shim_table = {
    OCS_VDB_SHIM_ABI,      (uint32_t)sizeof(ocs_vdb_api_t), shim_version,          shim_open,
    shim_close,            shim_file_info,                  shim_grid_count,       shim_grid_info,
    shim_grid_prepare,     shim_grid_free,                  shim_grid_levels,      shim_grid_sample,
    shim_grid_range,       shim_writer_create,              shim_writer_free,      shim_writer_add_grid,
    shim_writer_set_values, shim_writer_fill,               shim_writer_add_points, shim_writer_set_meta,
    shim_writer_save,
};

}  // namespace

extern "C" __attribute__((visibility("default"))) const ocs_vdb_api_t *ocs_vdb_shim_api(uint32_t abi) {
  if (abi != OCS_VDB_SHIM_ABI) return nullptr;
  static std::once_flag once;
  static bool ok = false;
  try {
    std::call_once(once, [] {
      openvdb::initialize();
      ok = true;
    });
  } catch (...) {
    return nullptr;
  }
  return ok ? &shim_table : nullptr;
}
