// Tile-based Gaussian splat compositing for the CPU, forward and hand-written backward.
//
// Semantics match anigs/render/torch_backend.py exactly (see its docstring).
// Layout: splats are pre-sorted front to back; rects are half-open pixel boxes.
// Parallelism: OpenMP over 16x16 tiles. The backward writes one gradient row per
// (tile, splat) pair and reduces them per splat in a fixed order, so results are
// bit-identical whatever the thread count.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <algorithm>
#ifdef _OPENMP
#include <omp.h>
#endif

namespace {
constexpr int TILE = 16;
constexpr int TPIX = TILE * TILE;
constexpr int MAXC = 32;
constexpr float ALPHA_MIN = 1.0f / 255.0f;
constexpr float ALPHA_MAX = 0.99f;
constexpr float T_MIN = 1e-4f;

inline int tiles_of(int n) { return (n + TILE - 1) / TILE; }

struct Box { int x0, y0, x1, y1; };

inline bool overlap(const int* r, int tx, int ty, int W, int H, Box& b) {
  b.x0 = std::max(r[0], tx * TILE);
  b.y0 = std::max(r[1], ty * TILE);
  b.x1 = std::min(r[2], std::min(W, (tx + 1) * TILE));
  b.y1 = std::min(r[3], std::min(H, (ty + 1) * TILE));
  return b.x0 < b.x1 && b.y0 < b.y1;
}

// alpha and exponent of splat g at pixel (x, y); returns false when skipped.
inline bool splat_alpha(const float* m, const float* q, float o, int x, int y,
                        float& dx, float& dy, float& G, float& alpha) {
  dx = (float(x) + 0.5f) - m[0];
  dy = (float(y) + 0.5f) - m[1];
  float power = -0.5f * (q[0] * dx * dx + q[2] * dy * dy) - q[1] * dx * dy;
  if (power > 0.f) return false;
  G = std::exp(power);
  alpha = std::min(ALPHA_MAX, o * G);
  return alpha >= ALPHA_MIN;
}
// Pixels of row y (within [bx0, bx1)) where the splat can reach alpha >= 1/255:
// A dx^2 + 2 B dy dx + C dy^2 <= 2 ln(255 o), with a small safety margin (the per-pixel
// alpha test still decides, so this only skips work).
inline bool row_span(const float* m, const float* q, float lv2, int y, int bx0, int bx1, int& xs, int& xe) {
  const float dy = (float(y) + 0.5f) - m[1];
  const float bdy = q[1] * dy;
  const float disc = bdy * bdy - q[0] * (q[2] * dy * dy - lv2);
  if (disc < 0.f) return false;
  const float r = std::sqrt(disc);
  const float lo = m[0] - 0.5f + (-bdy - r) / q[0] - 0.05f;
  const float hi = m[0] - 0.5f + (-bdy + r) / q[0] + 0.05f;
  xs = std::max(bx0, int(std::ceil(std::max(lo, -1e7f))));
  xe = std::min(bx1, int(std::floor(std::min(hi, 1e7f))) + 1);
  return xs < xe;
}
}  // namespace

extern "C" {

int anigs_abi_version() { return 3; }

int anigs_max_channels() { return MAXC; }

// Number of tiles each splat overlaps (0 for empty rects).
void anigs_tile_counts(int M, const int* rects, int W, int H, int* counts) {
  for (int g = 0; g < M; ++g) {
    const int* r = rects + 4 * g;
    if (r[2] <= r[0] || r[3] <= r[1]) { counts[g] = 0; continue; }
    int tx0 = r[0] / TILE, tx1 = (r[2] - 1) / TILE, ty0 = r[1] / TILE, ty1 = (r[3] - 1) / TILE;
    counts[g] = (tx1 - tx0 + 1) * (ty1 - ty0 + 1);
  }
}

// Counting sort of (tile, splat) pairs by tile; splat order (depth) is kept within a tile.
// tile_offsets [ntiles+1] out; tile_splats [npairs] out; pair_slots [npairs] out, splat-major
// (pair_slots[gstart[g] + k] = slot of the k-th tile of splat g).
void anigs_bin(int M, const int* rects, int W, int H, const int* gstart,
               int* tile_offsets, int* tile_splats, int* pair_slots) {
  const int TX = tiles_of(W), TY = tiles_of(H), NT = TX * TY;
  std::memset(tile_offsets, 0, sizeof(int) * (NT + 1));
  for (int g = 0; g < M; ++g) {
    const int* r = rects + 4 * g;
    if (r[2] <= r[0] || r[3] <= r[1]) continue;
    for (int ty = r[1] / TILE; ty <= (r[3] - 1) / TILE; ++ty)
      for (int tx = r[0] / TILE; tx <= (r[2] - 1) / TILE; ++tx) tile_offsets[ty * TX + tx + 1]++;
  }
  for (int t = 0; t < NT; ++t) tile_offsets[t + 1] += tile_offsets[t];
  int* fill = new int[NT];
  std::memcpy(fill, tile_offsets, sizeof(int) * NT);
  for (int g = 0; g < M; ++g) {
    const int* r = rects + 4 * g;
    if (r[2] <= r[0] || r[3] <= r[1]) continue;
    int k = gstart[g];
    for (int ty = r[1] / TILE; ty <= (r[3] - 1) / TILE; ++ty)
      for (int tx = r[0] / TILE; tx <= (r[2] - 1) / TILE; ++tx) {
        int slot = fill[ty * TX + tx]++;
        tile_splats[slot] = g;
        pair_slots[k++] = slot;
      }
  }
  delete[] fill;
}

// Forward. out_feat [H,W,C] accumulated features (no background), out_T [H,W] final
// transmittance, out_last [H,W] one past the last contributing position in the tile list.
void anigs_forward(int M, int C, int W, int H, const float* means2d, const float* conics,
                   const float* feats, const float* opac, const int* rects,
                   const int* tile_offsets, const int* tile_splats,
                   float* out_feat, float* out_T, int* out_last, int nthreads) {
  const int TX = tiles_of(W), TY = tiles_of(H), NT = TX * TY;
#ifdef _OPENMP
  if (nthreads < 1) nthreads = omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
#endif
  for (int t = 0; t < NT; ++t) {
    const int tx = t % TX, ty = t / TX;
    const int px0 = tx * TILE, py0 = ty * TILE;
    const int tw = std::min(TILE, W - px0), th = std::min(TILE, H - py0);
    float T[TPIX], acc[TPIX * MAXC];
    int last[TPIX];
    unsigned char done[TPIX];
    for (int p = 0; p < TPIX; ++p) { T[p] = 1.f; last[p] = 0; done[p] = 0; }
    std::memset(acc, 0, sizeof(float) * TPIX * C);
    int ndone = 0;
    const int npix = tw * th;
    for (int j = tile_offsets[t]; j < tile_offsets[t + 1] && ndone < npix; ++j) {
      const int g = tile_splats[j];
      Box b;
      if (!overlap(rects + 4 * g, tx, ty, W, H, b)) continue;
      const float* m = means2d + 2 * g;
      const float* q = conics + 3 * g;
      const float o = opac[g];
      const float* f = feats + (size_t)C * g;
      const int jl = j - tile_offsets[t];
      const float lv2 = 2.f * std::log(std::max(o * 255.f, 1.f));
      for (int y = b.y0; y < b.y1; ++y) {
        int xs, xe;
        if (!row_span(m, q, lv2, y, b.x0, b.x1, xs, xe)) continue;
        for (int x = xs; x < xe; ++x) {
          const int p = (y - py0) * TILE + (x - px0);
          if (done[p]) continue;
          float dx, dy, G, alpha;
          if (!splat_alpha(m, q, o, x, y, dx, dy, G, alpha)) continue;
          const float nextT = T[p] * (1.f - alpha);
          if (nextT <= T_MIN) { done[p] = 1; ++ndone; continue; }
          const float w = alpha * T[p];
          float* a = acc + p * C;
          for (int c = 0; c < C; ++c) a[c] += w * f[c];
          T[p] = nextT;
          last[p] = jl + 1;
        }
      }
    }
    for (int y = 0; y < th; ++y)
      for (int x = 0; x < tw; ++x) {
        const int p = y * TILE + x;
        const size_t o = (size_t)(py0 + y) * W + (px0 + x);
        out_T[o] = T[p];
        out_last[o] = last[p];
        std::memcpy(out_feat + o * C, acc + p * C, sizeof(float) * C);
      }
  }
}

// Backward. Inputs: forward outputs out_feat/out_T/out_last and upstream grads
// g_feat [H,W,C], g_T [H,W]. Writes per-pair rows into pair_grads [npairs, 6+C]:
// (d mean_x, d mean_y, d conic_a, d conic_b, d conic_c, d opacity, d feats...).
void anigs_backward(int M, int C, int W, int H, const float* means2d, const float* conics,
                    const float* feats, const float* opac, const int* rects,
                    const int* tile_offsets, const int* tile_splats,
                    const float* out_T, const int* out_last,
                    const float* g_feat, const float* g_T, float* pair_grads, int nthreads) {
  const int TX = tiles_of(W), TY = tiles_of(H), NT = TX * TY;
  const int D = 6 + C;
#ifdef _OPENMP
  if (nthreads < 1) nthreads = omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
#endif
  for (int t = 0; t < NT; ++t) {
    const int tx = t % TX, ty = t / TX;
    const int px0 = tx * TILE, py0 = ty * TILE;
    const int tw = std::min(TILE, W - px0), th = std::min(TILE, H - py0);
    float T[TPIX], Tfin[TPIX], gT[TPIX], S[TPIX * MAXC], gF[TPIX * MAXC];
    int last[TPIX];
    int maxlast = 0;
    for (int p = 0; p < TPIX; ++p) last[p] = 0;
    for (int y = 0; y < th; ++y)
      for (int x = 0; x < tw; ++x) {
        const int p = y * TILE + x;
        const size_t o = (size_t)(py0 + y) * W + (px0 + x);
        T[p] = Tfin[p] = out_T[o];
        gT[p] = g_T[o];
        last[p] = out_last[o];
        maxlast = std::max(maxlast, last[p]);
        std::memcpy(gF + p * C, g_feat + o * C, sizeof(float) * C);
        for (int c = 0; c < C; ++c) S[p * C + c] = 0.f;
      }
    float sum[6 + MAXC];
    for (int jl = maxlast - 1; jl >= 0; --jl) {
      const int j = tile_offsets[t] + jl;
      const int g = tile_splats[j];
      Box b;
      if (!overlap(rects + 4 * g, tx, ty, W, H, b)) continue;
      const float* m = means2d + 2 * g;
      const float* q = conics + 3 * g;
      const float o = opac[g];
      const float* f = feats + (size_t)C * g;
      for (int d = 0; d < D; ++d) sum[d] = 0.f;
      const float lv2 = 2.f * std::log(std::max(o * 255.f, 1.f));
      for (int y = b.y0; y < b.y1; ++y) {
        int xs, xe;
        if (!row_span(m, q, lv2, y, b.x0, b.x1, xs, xe)) continue;
        for (int x = xs; x < xe; ++x) {
          const int p = (y - py0) * TILE + (x - px0);
          if (jl >= last[p]) continue;
          float dx, dy, G, alpha;
          if (!splat_alpha(m, q, o, x, y, dx, dy, G, alpha)) continue;
          const float inv = 1.f / (1.f - alpha);
          const float Tj = T[p] * inv;  // transmittance in front of this splat
          const float w = alpha * Tj;
          float* s = S + p * C;
          const float* gf = gF + p * C;
          float dA = -gT[p] * Tfin[p] * inv;
          for (int c = 0; c < C; ++c) {
            sum[6 + c] += w * gf[c];
            dA += gf[c] * (f[c] * Tj - s[c] * inv);
            s[c] += f[c] * w;
          }
          T[p] = Tj;
          if (o * G > ALPHA_MAX) continue;  // clamped: no gradient to o or the exponent
          const float dP = dA * alpha;  // d alpha / d power = alpha
          sum[5] += dA * G;
          sum[0] += dP * (q[0] * dx + q[1] * dy);
          sum[1] += dP * (q[1] * dx + q[2] * dy);
          sum[2] += dP * (-0.5f * dx * dx);
          sum[3] += dP * (-dx * dy);
          sum[4] += dP * (-0.5f * dy * dy);
        }
      }
      std::memcpy(pair_grads + (size_t)j * D, sum, sizeof(float) * D);
    }
  }
}

// Sum per-pair gradient rows into per-splat gradients [M, D] in a fixed order.
void anigs_reduce(int M, int D, const int* gstart, const int* gcount, const int* pair_slots,
                  const float* pair_grads, float* out, int nthreads) {
#ifdef _OPENMP
  if (nthreads < 1) nthreads = omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(nthreads)
#endif
  for (int g = 0; g < M; ++g) {
    float* o = out + (size_t)g * D;
    for (int d = 0; d < D; ++d) o[d] = 0.f;
    for (int k = 0; k < gcount[g]; ++k) {
      const float* r = pair_grads + (size_t)pair_slots[gstart[g] + k] * D;
      for (int d = 0; d < D; ++d) o[d] += r[d];
    }
  }
}

}  // extern "C"
#include "project.cpp"
