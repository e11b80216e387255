// Tile-based Gaussian splat compositing for the CPU, forward and hand-written backward.
//
// Semantics match anigs/render/torch_backend.py and the tail of rasterize() (background,
// alpha, expected depth) exactly; see their docstrings. Pipeline per call:
//   anigs_preprocess          per-Gaussian projection + colour (project.cpp)
//   anigs_sort_count          visible splats sorted front to back (stable radix sort on depth),
//                             per-splat tile counts (the tiles its ellipse reaches, cull.cpp)
//   anigs_composite_forward   tile binning (each pair with its sub-rectangle of the tile),
//                             compositing, rgb/alpha/depth
//   anigs_composite_backward  per-(tile, splat) gradient rows, reduced per splat in a fixed order
//   anigs_composite_weights   forward-only alternative to forward + backward for the per-splat
//                             blend weight sums sum_p alpha T factor(p) (mask lifting, visibility)
//   anigs_preprocess_backward (project.cpp)
// Parallelism: OpenMP (or pool.cpp's threads) over Gaussians and over 16x16 tiles. Inside
// a tile, a splat's box rows are processed in vector windows (GCC/Clang vector extensions:
// 16/8 lanes with AVX-512, 8 with AVX2, 4 with SSE or NEON), in two passes per (tile, splat)
// pair: the exponentials of all its rows (PairEval::eval), then the compositing (or its
// backward) over those rows. The row loops have no data-dependent branches on the alpha
// tests (masked lanes are no-ops): such branches mispredict often and cost more than the
// few rows they skip. Every reduction has a fixed order, so results are bit-identical
// whatever the thread count.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <algorithm>
#include <memory>
#include <vector>
#include "pool.cpp"
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

// Vector helpers must inline: without AVX-512, 64-byte vectors cross calls through memory.
#define ANIGS_INLINE inline __attribute__((always_inline))

namespace {
constexpr int TILE = 16;
constexpr int NCH = 4;  // composited channels: r, g, b, depth
constexpr int D = 6 + NCH;  // gradient row: mean x/y, conic a/b/c, opacity, channels
constexpr float ALPHA_MIN = 1.0f / 255.0f;
constexpr float ALPHA_MAX = 0.99f;
constexpr float T_MIN = 1e-4f;
constexpr int PREFETCH = 4;  // splat records fetched this many list entries ahead
// Row windows: with AVX-512 a box at most 8 pixels wide takes one 8-lane window and a wider
// one the whole 16-lane tile row; otherwise boxes are covered by windows of the hardware's
// vector width (GCC scalarizes comparisons on vectors wider than the hardware's).
#if defined(__AVX512F__)
constexpr bool WIDE16 = true;
constexpr int NW = 8;
#elif defined(__AVX__)
constexpr bool WIDE16 = false;
constexpr int NW = 8;
#else
constexpr bool WIDE16 = false;
constexpr int NW = 4;
#endif

inline int tiles_of(int n) { return (n + TILE - 1) / TILE; }

// ---- lane vectors: 16 lanes = one tile row, 8 lanes = a window on a narrow box ----
template <int L> struct VT;
template <> struct VT<16> {
  typedef float f __attribute__((vector_size(64)));
  typedef int32_t i __attribute__((vector_size(64)));
};
template <> struct VT<8> {
  typedef float f __attribute__((vector_size(32)));
  typedef int32_t i __attribute__((vector_size(32)));
};
template <> struct VT<4> {
  typedef float f __attribute__((vector_size(16)));
  typedef int32_t i __attribute__((vector_size(16)));
};
typedef VT<16>::f vf16;
typedef VT<16>::i vi16;
typedef VT<8>::f vf8;
typedef VT<8>::i vi8;
typedef VT<4>::f vf4;
typedef VT<4>::i vi4;

template <class V> ANIGS_INLINE V ld(const void* p) {
  V v;
  std::memcpy(&v, p, sizeof(V));
  return v;
}
template <class V> ANIGS_INLINE void st(void* p, V v) { std::memcpy(p, &v, sizeof(V)); }
template <class F> ANIGS_INLINE F bc(float s) { return F{} + s; }
template <class I> ANIGS_INLINE I bci(int32_t s) { return I{} + s; }
template <class I, class F> ANIGS_INLINE F sel(I m, F a, F b) { return (F)(((I)a & m) | ((I)b & ~m)); }
template <class I> ANIGS_INLINE I seli(I m, I a, I b) { return (a & m) | (b & ~m); }

#if defined(__AVX512F__)
ANIGS_INLINE unsigned bits(vi16 m) { return _mm512_test_epi32_mask((__m512i)m, (__m512i)m); }
#elif defined(__AVX2__)
ANIGS_INLINE unsigned bits(vi16 m) {
  __m256i h[2];
  std::memcpy(h, &m, sizeof(m));
  return (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(h[0])) |
         ((unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(h[1])) << 8);
}
#endif
#if defined(__AVX512F__) || defined(__AVX2__)
ANIGS_INLINE unsigned bits(vi8 m) { return (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps((__m256i)m)); }
ANIGS_INLINE bool any(vi16 m) { return bits(m) != 0; }
ANIGS_INLINE bool any(vi8 m) { return bits(m) != 0; }
ANIGS_INLINE int count(vi16 m) { return __builtin_popcount(bits(m)); }
#endif
#if defined(__SSE__)
ANIGS_INLINE bool any(vi4 m) { return _mm_movemask_ps(_mm_castsi128_ps((__m128i)m)) != 0; }
#endif
#if !defined(__AVX512F__) && !defined(__AVX2__)
template <class I> ANIGS_INLINE bool any(I m) {
  int32_t r = 0;
  for (int i = 0; i < int(sizeof(I) / 4); ++i) r |= m[i];
  return r != 0;
}
ANIGS_INLINE int count(vi16 m) {
  int r = 0;
  for (int i = 0; i < 16; ++i) r -= m[i];
  return r;
}
#endif
// Lane sums in a fixed tree order.
ANIGS_INLINE float hsum(vf4 v) { return (v[0] + v[2]) + (v[1] + v[3]); }
ANIGS_INLINE float hsum(vf8 v) { return ((v[0] + v[4]) + (v[2] + v[6])) + ((v[1] + v[5]) + (v[3] + v[7])); }
ANIGS_INLINE float hsum(vf16 v) {
  float a[8];
  for (int i = 0; i < 8; ++i) a[i] = v[i] + v[i + 8];
  return ((a[0] + a[4]) + (a[2] + a[6])) + ((a[1] + a[5]) + (a[3] + a[7]));
}
// out[d] += lane sum of v[d], d < N, in a fixed order. With AVX the first eight sums come
// from one transpose-and-add tree (14 shuffles, 7 adds) instead of eight separate
// horizontal sums (each a chain of lane extracts): the backward pays this once per
// (tile, splat) pair, which for small splats costs as much as a few rows.
template <int N> ANIGS_INLINE void add_sums(const vf4 (&v)[N], float* out) {
  for (int d = 0; d < N; ++d) out[d] += hsum(v[d]);
}
template <int N> ANIGS_INLINE void add_sums(const vf8 (&v)[N], float* out) {
  int d = 0;
#if defined(__AVX__)
  if (N >= 8) {
    __m256 a[8];
    std::memcpy(a, v, sizeof(a));
    __m256 p[4], q[2];
    for (int i = 0; i < 4; ++i)  // per 128-bit half: (a0+a2, b0+b2, a1+a3, b1+b3)
      p[i] = _mm256_add_ps(_mm256_unpacklo_ps(a[2 * i], a[2 * i + 1]), _mm256_unpackhi_ps(a[2 * i], a[2 * i + 1]));
    for (int i = 0; i < 2; ++i)  // per half: one partial sum for each of 4 vectors
      q[i] = _mm256_add_ps(_mm256_shuffle_ps(p[2 * i], p[2 * i + 1], 0x44),
                           _mm256_shuffle_ps(p[2 * i], p[2 * i + 1], 0xee));
    const __m256 r = _mm256_add_ps(_mm256_permute2f128_ps(q[0], q[1], 0x20), _mm256_permute2f128_ps(q[0], q[1], 0x31));
    alignas(32) float t[8];
    _mm256_store_ps(t, r);
    for (int i = 0; i < 8; ++i) out[i] += t[i];
    d = 8;
  }
#endif
  for (; d < N; ++d) out[d] += hsum(v[d]);
}
template <int N> ANIGS_INLINE void add_sums(const vf16 (&v)[N], float* out) {
  vf8 h[N];  // fold the two 8-lane halves first
  for (int d = 0; d < N; ++d) {
    vf8 lo, hi;
    std::memcpy(&lo, &v[d], sizeof(lo));
    std::memcpy(&hi, reinterpret_cast<const char*>(&v[d]) + sizeof(lo), sizeof(hi));
    h[d] = lo + hi;
  }
  add_sums<N>(h, out);
}

// vmin(a, b) = a < b ? a : b and vmax(a, b) = a > b ? a : b lane-wise (b where a is NaN):
// one instruction each on x86 (minps/maxps have exactly these semantics), where the
// generic select takes a compare and a blend.
#if defined(__AVX512F__)
ANIGS_INLINE vf16 vmin(vf16 a, vf16 b) { return (vf16)_mm512_min_ps((__m512)a, (__m512)b); }
ANIGS_INLINE vf16 vmax(vf16 a, vf16 b) { return (vf16)_mm512_max_ps((__m512)a, (__m512)b); }
#else
ANIGS_INLINE vf16 vmin(vf16 a, vf16 b) { return sel(a < b, a, b); }
ANIGS_INLINE vf16 vmax(vf16 a, vf16 b) { return sel(a > b, a, b); }
#endif
#if defined(__AVX__)
ANIGS_INLINE vf8 vmin(vf8 a, vf8 b) { return (vf8)_mm256_min_ps((__m256)a, (__m256)b); }
ANIGS_INLINE vf8 vmax(vf8 a, vf8 b) { return (vf8)_mm256_max_ps((__m256)a, (__m256)b); }
#else
ANIGS_INLINE vf8 vmin(vf8 a, vf8 b) { return sel(a < b, a, b); }
ANIGS_INLINE vf8 vmax(vf8 a, vf8 b) { return sel(a > b, a, b); }
#endif
#if defined(__SSE__)
ANIGS_INLINE vf4 vmin(vf4 a, vf4 b) { return (vf4)_mm_min_ps((__m128)a, (__m128)b); }
ANIGS_INLINE vf4 vmax(vf4 a, vf4 b) { return (vf4)_mm_max_ps((__m128)a, (__m128)b); }
#else
ANIGS_INLINE vf4 vmin(vf4 a, vf4 b) { return sel(a < b, a, b); }
ANIGS_INLINE vf4 vmax(vf4 a, vf4 b) { return sel(a > b, a, b); }
#endif

// a * b + c, fused (one rounding) where the hardware has FMA. Only vexp uses it: its
// polynomial is an approximation anyway, and fusing shortens its dependency chain, which
// bounds the row loops. (Elsewhere -ffp-contract=off keeps the reference's operation order.)
#if defined(__FMA__)
ANIGS_INLINE vf4 fmadd(vf4 a, vf4 b, vf4 c) { return (vf4)_mm_fmadd_ps((__m128)a, (__m128)b, (__m128)c); }
ANIGS_INLINE vf8 fmadd(vf8 a, vf8 b, vf8 c) { return (vf8)_mm256_fmadd_ps((__m256)a, (__m256)b, (__m256)c); }
#else
template <class F> ANIGS_INLINE F fmadd(F a, F b, F c) { return a * b + c; }
#endif
#if defined(__AVX512F__)
ANIGS_INLINE vf16 fmadd(vf16 a, vf16 b, vf16 c) { return (vf16)_mm512_fmadd_ps((__m512)a, (__m512)b, (__m512)c); }
#elif defined(__FMA__)
ANIGS_INLINE vf16 fmadd(vf16 a, vf16 b, vf16 c) { return a * b + c; }
#endif

// exp(x) for float lanes (Cephes expf: Cody-Waite reduction + degree-7 polynomial,
// ~1 ulp). x is clamped at -87 so far-away lanes stay finite; only x <= 0 is used.
template <class F, class I> ANIGS_INLINE F vexp(F x) {
  x = vmax(x, bc<F>(-87.f));
  const F magic = bc<F>(12582912.f);  // 1.5 * 2^23: adding it rounds to an integer
  const F t = fmadd(x, bc<F>(1.44269504088896341f), magic);
  const F n = t - magic;
  const I ni = (I)t - (I)magic;
  F r = fmadd(n, bc<F>(-0.693359375f), x);
  r = fmadd(n, bc<F>(2.12194440e-4f), r);
  // p(r) = sum_k p_k r^k, k = 0..5, in Estrin's scheme (short dependency chains)
  const F r2 = r * r, r4 = r2 * r2;
  const F p01 = fmadd(r, bc<F>(1.6666665459e-1f), bc<F>(5.0000001201e-1f));
  const F p23 = fmadd(r, bc<F>(8.3334519073e-3f), bc<F>(4.1665795894e-2f));
  const F p45 = fmadd(r, bc<F>(1.9875691500e-4f), bc<F>(1.3981999507e-3f));
  const F p = fmadd(r4, p45, fmadd(r2, p23, p01));
  const F y = fmadd(p, r2, r) + 1.f;
  return y * (F)((ni + 127) << 23);
}
alignas(64) const int32_t LANE_I[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
alignas(64) const float LANE_C[16] = {0.5f, 1.5f, 2.5f, 3.5f, 4.5f, 5.5f, 6.5f, 7.5f,
                                      8.5f, 9.5f, 10.5f, 11.5f, 12.5f, 13.5f, 14.5f, 15.5f};

// Copy n <= 16 values (4 bytes each): a fixed-size copy for full tile rows, so it is inlined.
ANIGS_INLINE void copy_row(void* dst, const void* src, int n) {
  if (n == TILE) std::memcpy(dst, src, 4 * TILE);
  else std::memcpy(dst, src, 4 * (size_t)n);
}

// A visible splat, packed in depth order (one cache line).
struct Rec {
  float mx, my, A, B, C, o, pad0, pad1;
  float f[NCH];
  int32_t x0, y0, x1, y1;
};
static_assert(sizeof(Rec) == 64, "Rec must be 16 floats");

// A splat's exponent over L lanes of a tile row starting at pixel ax, and the lanes inside
// its box [bx0, bx1). The exponent is
//   power = -0.5 (A dx^2 + C dy^2) - B dx dy,  dx = x + 0.5 - mean_x, dy = y + 0.5 - mean_y
// evaluated in that operation order (as the torch reference); the box (not an ellipse span
// test) limits the pixels, the per-pixel alpha >= 1/255 test does the rest.
template <int L> struct PairEval {
  typedef typename VT<L>::f F;
  typedef typename VT<L>::i I;
  F dx, Adx2, Bdx;
  I box;
  ANIGS_INLINE PairEval(const Rec& s, int ax, int bx0, int bx1) {
    dx = (ld<F>(LANE_C) + float(ax)) - s.mx;  // float(x) + 0.5 - mean_x, exactly
    Adx2 = s.A * dx * dx;
    Bdx = s.B * dx;
    const I li = ld<I>(LANE_I);
    box = (li >= bci<I>(bx0 - ax)) & (li < bci<I>(bx1 - ax));
  }
  // G, alpha and the lanes passing the box, exponent and 1/255 tests, for rows [y0, y1).
  // This runs as a pass of its own before the compositing pass: its rows are independent
  // and short, so the CPU overlaps many exp evaluations (the longest dependency chain of a
  // row); fused into the compositing loop, whose rows are long, only a few rows fit in the
  // out-of-order window and the exp latency is exposed on every row.
  template <class Rows> ANIGS_INLINE void eval(const Rec& s, int y0, int y1, Rows& r) const {
    for (int y = y0; y < y1; ++y) {
      const float dy = (float(y) + 0.5f) - s.my;
      const float cdy = s.C * dy * dy;
      const F power = -0.5f * (Adx2 + cdy) - Bdx * dy;
      const F G = vexp<F, I>(power);
      const F oG = s.o * G;
      const F alpha = vmin(oG, bc<F>(ALPHA_MAX));
      const int i = y - y0;
      r.G[i] = G;
      r.alpha[i] = alpha;
      r.m[i] = box & (power <= 0.f) & (alpha >= ALPHA_MIN);
    }
  }
};
// Per-row results of PairEval::eval for one pair (at most TILE rows).
template <int L> struct Rows {
  typename VT<L>::f G[TILE], alpha[TILE];
  typename VT<L>::i m[TILE];
};

// Per-tile pixel state: 16 rows, each padded to RS lanes so a window may start at any of
// the 16 columns.
constexpr int RS = 32;
struct FwdTile {
  alignas(64) float T[TILE * RS];
  alignas(64) float acc[NCH][TILE * RS];
  alignas(64) int32_t last[TILE * RS];
  alignas(64) int32_t done[TILE * RS];
};
struct BwdTile {
  alignas(64) float T[TILE * RS];     // transmittance behind the current splat (final T at first)
  alignas(64) float gTT[TILE * RS];  // -gT * T_final: d out / d alpha via the final transmittance, times (1 - alpha)
  alignas(64) float GS[TILE * RS];  // sum_c gF_c S_c, S_c = channel sum behind the current splat
  alignas(64) float gF[NCH][TILE * RS];
  alignas(64) int32_t last[TILE * RS];
};

#include "cull.cpp"

// Composite splat s (list position jl1 - 1) over rows [by0, by1) of the L-lane window at
// pixel column ax (= px0 + off). Returns true when some pixel hit the transmittance floor.
// NCW = 0: the image forward (channel sums acc, last). NCW = 1..3: the blend weights only
// (anigs_composite_weights): acc and last are left alone, and out[c] (c < NCW) gets the sum
// over the window of w(p) fac[c](p), fac = the tile's factor rows ([NCW][TILE * RS]).
template <int L, int NCW = 0>
ANIGS_INLINE bool forward_pair(const Rec& s, int ax, int off, int bx0, int bx1, int by0, int by1, int py0, int jl1,
                         FwdTile& t, const float* fac = nullptr, float* out = nullptr) {
  typedef typename VT<L>::f F;
  typedef typename VT<L>::i I;
  const PairEval<L> pe(s, ax, bx0, bx1);
  Rows<L> rw;
  pe.eval(s, by0, by1, rw);
  const I jl1v = bci<I>(jl1);
  I term_any = bci<I>(0);
  F wsum[NCW > 0 ? NCW : 1];
  for (int c = 0; c < NCW; ++c) wsum[c] = bc<F>(0.f);
  for (int y = by0; y < by1; ++y) {
    const int k = (y - py0) * RS + off;
    const I done = ld<I>(t.done + k);
    if (!any(pe.box & ~done)) continue;  // every pixel of the row already stopped
    const F alpha = rw.alpha[y - by0];
    I m = rw.m[y - by0] & ~done;
    const F Tr = ld<F>(t.T + k);
    const F nextT = Tr * (1.f - alpha);
    const I term = m & (nextT <= T_MIN);  // stop before the splat crossing the floor
    st(t.done + k, done | term);
    term_any |= term;
    m &= ~term;
    const F w = sel(m, alpha * Tr, bc<F>(0.f));
    if constexpr (NCW == 0) {
      for (int c = 0; c < NCH; ++c) st(t.acc[c] + k, ld<F>(t.acc[c] + k) + w * s.f[c]);
    } else {
      for (int c = 0; c < NCW; ++c) wsum[c] += w * ld<F>(fac + c * (TILE * RS) + k);
    }
    st(t.T + k, sel(m, nextT, Tr));
    if constexpr (NCW == 0) st(t.last + k, seli(m, jl1v, ld<I>(t.last + k)));
  }
  if constexpr (NCW > 0) add_sums<NCW>(wsum, out);
  return any(term_any);
}

// Composite the tile's list [j0, j1) of sorted splats over the tile at (px0, py0), tw x th
// pixels, until every pixel has stopped (forward_pair's NCW; with NCW > 0 pair_w[j * NCW + c]
// gets pair j's weight sums and must be zero on entry).
template <int NCW = 0>
ANIGS_INLINE void composite_tile(const Rec* recs, const int* tile_splats, const int32_t* tile_rects, int j0, int j1,
                                 int px0, int py0, int tw, int th, FwdTile& tl, const float* fac = nullptr,
                                 float* pair_w = nullptr) {
  int ndone = 0;
  const int npix = tw * th;
  for (int j = j0; j < j1 && ndone < npix; ++j) {
    if (j + PREFETCH < j1) __builtin_prefetch(recs + tile_splats[j + PREFETCH]);
    const Rec& s = recs[tile_splats[j]];
    int bx0, by0, bx1, by1;
    if (!unpack_rect(tile_rects[j], px0, py0, bx0, by0, bx1, by1)) continue;
    const int jl1 = j - j0 + 1;
    float* out = NCW > 0 ? pair_w + (size_t)j * NCW : nullptr;
    bool term;
    if (WIDE16 && bx1 - bx0 > 8) {
      term = forward_pair<16, NCW>(s, px0, 0, bx0, bx1, by0, by1, py0, jl1, tl, fac, out);
    } else {  // windows left to right (pixels are independent: their order does not matter)
      term = false;
      for (int x = bx0; x < bx1; x += NW)
        term |= forward_pair<NW, NCW>(s, x, x - px0, bx0, bx1, by0, by1, py0, jl1, tl, fac, out);
    }
    if (term) {
      ndone = 0;
      for (int r = 0; r < th; ++r) ndone += count(ld<vi16>(tl.done + r * RS));
    }
  }
}

// Backward of splat s at list position jl: adds its gradient to out[D] and steps the
// per-pixel state back past it. NC = channels with a nonzero upstream gradient (3 when the
// depth output is unused, 4 otherwise).
template <int L, int NC>
ANIGS_INLINE void backward_pair(const Rec& s, int ax, int off, int bx0, int bx1, int by0, int by1, int py0, int jl,
                          BwdTile& t, float* out) {
  typedef typename VT<L>::f F;
  typedef typename VT<L>::i I;
  const PairEval<L> pe(s, ax, bx0, bx1);
  const F Adx = s.A * pe.dx, ndx = -pe.dx, hdx2 = -0.5f * pe.dx * pe.dx;
  const I jlv = bci<I>(jl);
  Rows<L> rw;
  pe.eval(s, by0, by1, rw);
  F sum[6 + NC];
  for (int d = 0; d < 6 + NC; ++d) sum[d] = bc<F>(0.f);
  for (int y = by0; y < by1; ++y) {
    const int k = (y - py0) * RS + off;
    const I live = pe.box & (jlv < ld<I>(t.last + k));
    if (!any(live)) continue;  // every pixel of the row stopped before this splat
    const float dy = (float(y) + 0.5f) - s.my;
    const F G = rw.G[y - by0], alpha = rw.alpha[y - by0];
    const I m = rw.m[y - by0] & live;
    const F Tk = ld<F>(t.T + k), GS = ld<F>(t.GS + k);
    const F inv = 1.f / (1.f - alpha);
    const F Tj = Tk * inv;  // transmittance in front of this splat
    const F w = sel(m, alpha * Tj, bc<F>(0.f));
    // d out / d alpha = -gT Tfin/(1-alpha) + sum_c gF_c (f_c Tj - S_c/(1-alpha))
    F gf[NC];
    for (int c = 0; c < NC; ++c) gf[c] = ld<F>(t.gF[c] + k);
    F Gf = gf[0] * s.f[0];
    for (int c = 1; c < NC; ++c) Gf += gf[c] * s.f[c];
    for (int c = 0; c < NC; ++c) sum[6 + c] += w * gf[c];
    const F dA = ld<F>(t.gTT + k) * inv + (Gf * Tj - GS * inv);
    st(t.GS + k, GS + Gf * w);
    st(t.T + k, sel(m, Tj, Tk));
    const I mc = m & (s.o * G <= ALPHA_MAX);  // clamped: no gradient to o or the exponent
    const F dP = sel(mc, dA * alpha, bc<F>(0.f));  // d alpha / d power = alpha
    sum[5] += sel(mc, dA * G, bc<F>(0.f));
    sum[0] += dP * (Adx + s.B * dy);
    sum[1] += dP * (pe.Bdx + s.C * dy);
    sum[2] += dP * hdx2;
    sum[3] += dP * (ndx * dy);
    sum[4] += dP * ((-0.5f * dy) * dy);
  }
  add_sums<6 + NC>(sum, out);
}

inline int nthreads_or_max(int n) { return n > 0 ? n : pool::max_threads(); }

// Order-preserving unsigned key of a float (ascending), -0 folded onto +0.
inline uint32_t float_key(float x) {
  x += 0.0f;
  uint32_t u;
  std::memcpy(&u, &x, 4);
  return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

// Binning (the first part of anigs_composite_forward): packs the M sorted splats into recs
// and bins the (tile, splat) pairs by tile (tile_offsets, tile_splats, tile_rects, and
// pair_slots unless null): the tiles of each splat's box that its ellipse reaches (cull.cpp);
// see anigs_composite_forward.
void bin_splats(int M, int W, int H, const int* order, const int* gstart, const float* means2d, const float* conics,
                const float* feats, const float* opac, const int* rects, Rec* recs, int* tile_offsets,
                int* tile_splats, int32_t* tile_rects, int* pair_slots, int nthreads) {
  const int TX = tiles_of(W), TY = tiles_of(H), NT = TX * TY;
  // Chunk k of the sorted splats packs its records, lists each splat's pairs (tile and
  // sub-rectangle, splat-major at gstart[m]) and counts its pairs per tile; after a prefix sum
  // over (tile, chunk) it moves its pairs to their tile-major slots. The result is the stable
  // order whatever the chunking.
  const size_t npairs = (size_t)gstart[M];
  std::unique_ptr<int32_t[]> ptile(new int32_t[std::max<size_t>(npairs, 1)]);
  std::unique_ptr<int32_t[]> prect(new int32_t[std::max<size_t>(npairs, 1)]);
  const int nchunk = std::max(1, std::min(4 * nthreads, M / 512));
  std::vector<int> hist((size_t)nchunk * NT, 0);
  const auto chunk_range = [&](int k, int& m0, int& m1) {
    m0 = (int)((long long)M * k / nchunk);
    m1 = (int)((long long)M * (k + 1) / nchunk);
  };
  pool::parallel_for(nchunk, nthreads, 1, [&](int kb, int ke) {
    for (int k = kb; k < ke; ++k) {
      int m0, m1;
      chunk_range(k, m0, m1);
      int* h = hist.data() + (size_t)k * NT;
      for (int m = m0; m < m1; ++m) {
        const int g = order[m];
        const int* r = rects + 4 * g;
        Rec& s = recs[m];
        s.mx = means2d[2 * g]; s.my = means2d[2 * g + 1];
        s.A = conics[3 * g]; s.B = conics[3 * g + 1]; s.C = conics[3 * g + 2];
        s.o = opac[g];
        s.pad0 = s.pad1 = 0.f;
        for (int c = 0; c < NCH; ++c) s.f[c] = feats[NCH * g + c];
        s.x0 = r[0]; s.y0 = r[1]; s.x1 = r[2]; s.y1 = r[3];
        const int n = splat_pairs(s, TX, ptile.get() + gstart[m], prect.get() + gstart[m]);
        for (int i = gstart[m]; i < gstart[m] + n; ++i) h[ptile[i]]++;
      }
    }
  });
  int sum = 0;
  for (int t = 0; t < NT; ++t) {
    tile_offsets[t] = sum;
    for (int k = 0; k < nchunk; ++k) {
      const int c = hist[(size_t)k * NT + t];
      hist[(size_t)k * NT + t] = sum;
      sum += c;
    }
  }
  tile_offsets[NT] = sum;

  pool::parallel_for(nchunk, nthreads, 1, [&](int kb, int ke) {
    for (int k = kb; k < ke; ++k) {
      int m0, m1;
      chunk_range(k, m0, m1);
      int* h = hist.data() + (size_t)k * NT;
      for (int m = m0; m < m1; ++m)
        for (int i = gstart[m]; i < gstart[m + 1]; ++i) {
          const int pos = h[ptile[i]]++;
          tile_splats[pos] = m;
          tile_rects[pos] = prect[i];
          if (pair_slots) pair_slots[i] = pos;
        }
    }
  });
}

// The tiles of anigs_composite_weights with NCW factor channels: pair_w [npairs, NCW].
template <int NCW>
void weights_tiles(int W, int H, const Rec* recs, const int* tile_offsets, const int* tile_splats,
                   const int32_t* tile_rects, const float* factors, float* pair_w, int nthreads) {
  const int TX = tiles_of(W), TY = tiles_of(H), NT = TX * TY;
  pool::parallel_for(NT, nthreads, 1, [&](int tb, int te) {
    for (int t = tb; t < te; ++t) {
      const int tx = t % TX, ty = t / TX;
      const int px0 = tx * TILE, py0 = ty * TILE;
      const int tw = std::min(TILE, W - px0), th = std::min(TILE, H - py0);
      const int j0 = tile_offsets[t], j1 = tile_offsets[t + 1];
      std::memset(pair_w + (size_t)j0 * NCW, 0, sizeof(float) * NCW * (size_t)(j1 - j0));
      if (j0 == j1) continue;
      FwdTile tl;  // acc and last unused here
      alignas(64) float fac[NCW][TILE * RS];
      for (int i = 0; i < TILE * RS; ++i) {
        tl.T[i] = 1.f;
        tl.done[i] = 0;
        for (int c = 0; c < NCW; ++c) fac[c][i] = 0.f;
      }
      for (int r = 0; r < th; ++r) {
        const float* src = factors + ((size_t)(py0 + r) * W + px0) * NCW;
        for (int x = 0; x < tw; ++x)
          for (int c = 0; c < NCW; ++c) fac[c][r * RS + x] = src[(size_t)x * NCW + c];
      }
      composite_tile<NCW>(recs, tile_splats, tile_rects, j0, j1, px0, py0, tw, th, tl, &fac[0][0], pair_w);
    }
  });
}
}  // namespace

extern "C" {

int anigs_abi_version() { return 5; }

int anigs_simd_bytes() {
#if defined(__AVX512F__)
  return 64;
#elif defined(__AVX2__) || defined(__AVX__)
  return 32;
#else
  return 16;
#endif
}

// Visible splats in front-to-back order: order[0..M) = indices g with valid[g], sorted by
// depth (feats[4g+3]) with ties in input order (stable LSD radix sort); gstart[0..M] =
// prefix sums of the number of tiles each sorted splat touches: the tiles of its box (rects
// [N,4]) that its ellipse reaches (means2d [N,2], conics [N,3], opac [N]; cull.cpp). Returns M;
// *npairs = gstart[M] (the number of (tile, splat) pairs).
int anigs_sort_count(int N, const float* feats, const unsigned char* valid, const int* rects, const float* means2d,
                     const float* conics, const float* opac, int W, int H, int* order, int* gstart,
                     long long* npairs, int nthreads) {
  (void)W; (void)H;
  int M = 0;
  std::vector<uint32_t> key((size_t)std::max(N, 1)), key2;
  std::vector<int> idx2;
  for (int g = 0; g < N; ++g)
    if (valid[g]) {
      key[M] = float_key(feats[4 * g + 3]);
      order[M++] = g;
    }
  if (M > 1) {
    // LSD radix sort, 4 passes of 8 bits (histograms in one sweep; constant digits skipped)
    key2.resize(M);
    idx2.resize(M);
    int hist[4][256] = {};
    for (int i = 0; i < M; ++i) {
      const uint32_t k = key[i];
      hist[0][k & 255]++; hist[1][(k >> 8) & 255]++; hist[2][(k >> 16) & 255]++; hist[3][k >> 24]++;
    }
    uint32_t* ka = key.data(); uint32_t* kb = key2.data();
    int* ia = order; int* ib = idx2.data();
    for (int pass = 0; pass < 4; ++pass) {
      int* h = hist[pass];
      const int shift = 8 * pass;
      if (h[(ka[0] >> shift) & 255] == M) continue;  // every key has this digit
      int sum = 0;
      for (int b = 0; b < 256; ++b) { const int c = h[b]; h[b] = sum; sum += c; }
      for (int i = 0; i < M; ++i) {
        const int pos = h[(ka[i] >> shift) & 255]++;
        kb[pos] = ka[i];
        ib[pos] = ia[i];
      }
      std::swap(ka, kb);
      std::swap(ia, ib);
    }
    if (ia != order) std::memcpy(order, ia, sizeof(int) * M);
  }
  std::vector<int> ntiles((size_t)std::max(N, 1));  // in input order: sequential reads
  pool::parallel_for(N, nthreads_or_max(nthreads), 1024, [&](int gb, int ge) {
    for (int g = gb; g < ge; ++g)
      if (valid[g]) ntiles[g] = culled_tiles(means2d + 2 * g, conics + 3 * g, opac[g], rects + 4 * g);
  });
  long long total = 0;
  gstart[0] = 0;
  for (int m = 0; m < M; ++m) {
    total += ntiles[order[m]];
    gstart[m + 1] = total > 0x7fffffffLL ? 0x7fffffff : int(total);
  }
  *npairs = total;
  return M;
}

// Forward. Packs the M sorted splats into recs [M,16] floats, bins (tile, splat) pairs by
// tile (tile_offsets [ntiles+1], tile_splats [npairs] = sorted splat index, depth order kept;
// tile_rects [npairs] = the pair's packed sub-rectangle of its tile (cull.cpp);
// pair_slots [npairs] splat-major: slot of the k-th tile of sorted splat m at gstart[m]+k),
// composites, and writes rgb [H,W,3] = acc + T bg, alpha [H,W] = 1 - T, depth [H,W] =
// acc_depth / alpha (0 where alpha = 0), and for the backward (all null when no gradient is
// needed) pair_slots, out_T, out_accd [H,W] and out_last [H,W] (one past the last
// contributing position in the tile's list).
void anigs_composite_forward(int M, int W, int H, const int* order, const int* gstart,
                             const float* means2d, const float* conics, const float* feats,
                             const float* opac, const int* rects, const float* bg,
                             float* recs_f, int* tile_offsets, int* tile_splats, int32_t* tile_rects,
                             int* pair_slots, float* out_rgb, float* out_alpha, float* out_depth,
                             float* out_T, float* out_accd, int* out_last, int nthreads) {
  Rec* recs = reinterpret_cast<Rec*>(recs_f);
  const int TX = tiles_of(W), TY = tiles_of(H), NT = TX * TY;
  nthreads = nthreads_or_max(nthreads);
  const float bgv[3] = {bg[0], bg[1], bg[2]};
  bin_splats(M, W, H, order, gstart, means2d, conics, feats, opac, rects, recs, tile_offsets, tile_splats,
             tile_rects, pair_slots, nthreads);

  pool::parallel_for(NT, nthreads, 1, [&](int tb, int te) {
    for (int t = tb; t < te; ++t) {
      const int tx = t % TX, ty = t / TX;
      const int px0 = tx * TILE, py0 = ty * TILE;
      const int tw = std::min(TILE, W - px0), th = std::min(TILE, H - py0);
      FwdTile tl;
      for (int i = 0; i < TILE * RS; ++i) {
        tl.T[i] = 1.f;
        tl.last[i] = tl.done[i] = 0;
        for (int c = 0; c < NCH; ++c) tl.acc[c][i] = 0.f;
      }
      composite_tile(recs, tile_splats, tile_rects, tile_offsets[t], tile_offsets[t + 1], px0, py0, tw, th, tl);
      for (int r = 0; r < th; ++r) {
        const int k = r * RS;
        const size_t o = (size_t)(py0 + r) * W + px0;
        const vf16 Tp = ld<vf16>(tl.T + k), ad = ld<vf16>(tl.acc[3] + k);
        const vf16 a = 1.f - Tp;
        const vf16 dep = sel(a > 0.f, ad / sel(a > 1e-10f, a, bc<vf16>(1e-10f)), bc<vf16>(0.f));
        alignas(64) float row[4][TILE];
        st(row[0], Tp); st(row[1], a); st(row[2], ad); st(row[3], dep);
        copy_row(out_alpha + o, row[1], tw);
        copy_row(out_depth + o, row[3], tw);
        if (out_T) {  // kept for the backward
          copy_row(out_T + o, row[0], tw);
          copy_row(out_accd + o, row[2], tw);
          copy_row(out_last + o, tl.last + k, tw);
        }
        float* rgb = out_rgb + 3 * o;
        for (int x = 0; x < tw; ++x)
          for (int c = 0; c < 3; ++c) rgb[3 * x + c] = tl.acc[c][k + x] + row[0][x] * bgv[c];
      }
    }
  });
}

// Blend weights only: the sort and binning of anigs_composite_forward and its compositing
// (same transmittance floor, alpha cutoff and clamp, so the weights are those of the image it
// renders), without the image. For each splat i and factor channel c < C (1..3) writes
//   out[i, c] = sum_p w_i(p) factors[p, c],  w_i(p) = alpha_i(p) T_i(p)
// (the d rgb_c / d colour_i of the forward; zero for splats that are not drawn). factors
// [H,W,C] float32 contiguous; out [N,C] float64. Sums per (tile, splat) pair in float, then
// per splat over its pairs in tile order (double): bit-identical whatever the thread count.
// Returns 0, or -1 for C outside 1..3 or when out of memory.
int anigs_composite_weights(int N, int M, int W, int H, const int* order, const int* gstart,
                            const float* means2d, const float* conics, const float* feats, const float* opac,
                            const int* rects, const float* factors, int C, double* out, int nthreads) {
  if (C < 1 || C > 3) return -1;
  nthreads = nthreads_or_max(nthreads);
  const int NT = tiles_of(W) * tiles_of(H);
  const size_t npairs = (size_t)gstart[M];
  Rec* recs = static_cast<Rec*>(std::aligned_alloc(64, sizeof(Rec) * (size_t)std::max(M, 1)));
  int* tile_offsets = static_cast<int*>(std::malloc(sizeof(int) * (size_t)(NT + 1)));
  int* tile_splats = static_cast<int*>(std::malloc(sizeof(int) * std::max<size_t>(npairs, 1)));
  int* pair_slots = static_cast<int*>(std::malloc(sizeof(int) * std::max<size_t>(npairs, 1)));
  int32_t* tile_rects = static_cast<int32_t*>(std::malloc(sizeof(int32_t) * std::max<size_t>(npairs, 1)));
  float* pair_w = static_cast<float*>(std::malloc(sizeof(float) * C * std::max<size_t>(npairs, 1)));
  int rc = -1;
  if (recs && tile_offsets && tile_splats && pair_slots && tile_rects && pair_w) {
    rc = 0;
    bin_splats(M, W, H, order, gstart, means2d, conics, feats, opac, rects, recs, tile_offsets, tile_splats,
               tile_rects, pair_slots, nthreads);
    if (C == 1) weights_tiles<1>(W, H, recs, tile_offsets, tile_splats, tile_rects, factors, pair_w, nthreads);
    else if (C == 2) weights_tiles<2>(W, H, recs, tile_offsets, tile_splats, tile_rects, factors, pair_w, nthreads);
    else weights_tiles<3>(W, H, recs, tile_offsets, tile_splats, tile_rects, factors, pair_w, nthreads);
    std::memset(out, 0, sizeof(double) * C * (size_t)N);  // splats not drawn
    pool::parallel_for(M, nthreads, 1024, [&](int mb, int me) {
      for (int m = mb; m < me; ++m) {
        double o[3] = {0.0, 0.0, 0.0};
        for (int k = gstart[m]; k < gstart[m + 1]; ++k) {
          const float* r = pair_w + (size_t)pair_slots[k] * C;
          for (int c = 0; c < C; ++c) o[c] += (double)r[c];
        }
        double* dst = out + (size_t)order[m] * C;
        for (int c = 0; c < C; ++c) dst[c] = o[c];
      }
    });
  }
  std::free(recs); std::free(tile_offsets); std::free(tile_splats); std::free(pair_slots); std::free(tile_rects);
  std::free(pair_w);
  return rc;
}

// Backward. Upstream grads g_rgb [H,W,3], g_alpha [H,W], g_depth [H,W] (each may be null =
// zero; any strides, gstrides). Writes every entry of g_means2d [N,2], g_conics [N,3], g_feats [N,4], g_opac [N]
// (zero for splats that are not visible, valid[g] = 0).
void anigs_composite_backward(int N, int M, int W, int H, const int* order, const int* gstart,
                              const unsigned char* valid, const float* recs_f, const int* tile_offsets,
                              const int* tile_splats, const int32_t* tile_rects, const int* pair_slots,
                              const float* bg,
                              const float* out_T, const float* out_accd, const int* out_last,
                              const float* g_rgb, const float* g_alpha, const float* g_depth,
                              const long long* gstrides, float* g_means2d, float* g_conics, float* g_feats,
                              float* g_opac, int nthreads) {
  // element strides: g_rgb (y, x, c), g_alpha (y, x), g_depth (y, x); e.g. 0 for expanded grads
  const long long rsy = gstrides[0], rsx = gstrides[1], rsc = gstrides[2];
  const long long asy = gstrides[3], asx = gstrides[4], dsy = gstrides[5], dsx = gstrides[6];
  const Rec* recs = reinterpret_cast<const Rec*>(recs_f);
  const int TX = tiles_of(W), TY = tiles_of(H), NT = TX * TY;
  const int npairs = tile_offsets[NT];
  float* pair_grads = static_cast<float*>(std::malloc(sizeof(float) * D * (size_t)std::max(npairs, 1)));
  const float bgv[3] = {bg[0], bg[1], bg[2]};
  nthreads = nthreads_or_max(nthreads);
  pool::parallel_for(NT, nthreads, 1, [&](int tb, int te) {
    for (int t = tb; t < te; ++t) {
      const int tx = t % TX, ty = t / TX;
      const int px0 = tx * TILE, py0 = ty * TILE;
      const int tw = std::min(TILE, W - px0), th = std::min(TILE, H - py0);
      BwdTile tl;
      int maxlast = 0;
      for (int i = 0; i < TILE * RS; ++i) {
        tl.T[i] = tl.gTT[i] = tl.GS[i] = 0.f;
        tl.last[i] = 0;
        for (int c = 0; c < NCH; ++c) tl.gF[c][i] = 0.f;
      }
      // the tail of rasterize(): rgb = acc + T bg, alpha = 1 - T, depth = acc_d / alpha
      for (int r = 0; r < th; ++r) {
        const int k = r * RS;
        const size_t o = (size_t)(py0 + r) * W + px0;
        copy_row(tl.T + k, out_T + o, tw);
        copy_row(tl.last + k, out_last + o, tw);
        alignas(64) float ga_[TILE] = {}, gd_[TILE] = {}, accd_[TILE] = {};
        const long long yy = py0 + r;
        if (g_alpha)
          for (int x = 0; x < tw; ++x) ga_[x] = g_alpha[yy * asy + (px0 + x) * asx];
        if (g_depth) {
          for (int x = 0; x < tw; ++x) gd_[x] = g_depth[yy * dsy + (px0 + x) * dsx];
          copy_row(accd_, out_accd + o, tw);
        }
        if (g_rgb)
          for (int x = 0; x < tw; ++x)
            for (int c = 0; c < 3; ++c) tl.gF[c][k + x] = g_rgb[yy * rsy + (px0 + x) * rsx + c * rsc];
        const vf16 a = 1.f - ld<vf16>(tl.T + k);
        vf16 gt = ld<vf16>(tl.gF[0] + k) * bgv[0];
        for (int c = 1; c < 3; ++c) gt += ld<vf16>(tl.gF[c] + k) * bgv[c];
        vf16 ga = ld<vf16>(ga_);
        const vf16 gd = ld<vf16>(gd_);
        const vf16 ac = sel(a > 1e-10f, a, bc<vf16>(1e-10f));  // max(a, 1e-10)
        const vi16 pos = a > 0.f;
        st(tl.gF[3] + k, sel(pos, gd / ac, bc<vf16>(0.f)));
        ga -= sel(pos & (a >= 1e-10f), gd * (ld<vf16>(accd_) / ac) / ac, bc<vf16>(0.f));
        st(tl.gTT + k, -(gt - ga) * ld<vf16>(tl.T + k));
        for (int x = 0; x < tw; ++x) maxlast = std::max(maxlast, tl.last[k + x]);
      }
      const int j0 = tile_offsets[t], j1 = tile_offsets[t + 1];
      for (int j = j0 + maxlast; j < j1; ++j) std::memset(pair_grads + (size_t)j * D, 0, sizeof(float) * D);
      for (int jl = maxlast - 1; jl >= 0; --jl) {
        const int j = j0 + jl;
        if (jl >= PREFETCH) __builtin_prefetch(recs + tile_splats[j - PREFETCH]);
        const Rec& s = recs[tile_splats[j]];
        float* row = pair_grads + (size_t)j * D;
        int bx0, by0, bx1, by1;
        std::memset(row, 0, sizeof(float) * D);
        if (!unpack_rect(tile_rects[j], px0, py0, bx0, by0, bx1, by1)) {
        } else if (WIDE16 && bx1 - bx0 > 8) {
          if (g_depth) backward_pair<16, 4>(s, px0, 0, bx0, bx1, by0, by1, py0, jl, tl, row);
          else backward_pair<16, 3>(s, px0, 0, bx0, bx1, by0, by1, py0, jl, tl, row);
        } else {
          for (int x = bx0; x < bx1; x += NW) {
            if (g_depth) backward_pair<NW, 4>(s, x, x - px0, bx0, bx1, by0, by1, py0, jl, tl, row);
            else backward_pair<NW, 3>(s, x, x - px0, bx0, bx1, by0, by1, py0, jl, tl, row);
          }
        }
      }
    }
  });
  // Per-splat sums of its pair rows in a fixed order; zeros for the splats not drawn.
  pool::parallel_for(std::max(N, M), nthreads, 1024, [&](int ib, int ie) {
    for (int g = ib; g < std::min(ie, N); ++g)
      if (!valid[g]) {
        g_means2d[2 * g] = g_means2d[2 * g + 1] = 0.f;
        g_conics[3 * g] = g_conics[3 * g + 1] = g_conics[3 * g + 2] = 0.f;
        for (int c = 0; c < NCH; ++c) g_feats[NCH * g + c] = 0.f;
        g_opac[g] = 0.f;
      }
    for (int m = ib; m < std::min(ie, M); ++m) {
      float o[D];
      for (int d = 0; d < D; ++d) o[d] = 0.f;
      for (int k = gstart[m]; k < gstart[m + 1]; ++k) {
        const float* r = pair_grads + (size_t)pair_slots[k] * D;
        for (int d = 0; d < D; ++d) o[d] += r[d];
      }
      const int g = order[m];
      g_means2d[2 * g] = o[0]; g_means2d[2 * g + 1] = o[1];
      g_conics[3 * g] = o[2]; g_conics[3 * g + 1] = o[3]; g_conics[3 * g + 2] = o[4];
      g_opac[g] = o[5];
      for (int c = 0; c < NCH; ++c) g_feats[NCH * g + c] = o[6 + c];
    }
  });
  std::free(pair_grads);
}

}  // extern "C"

#include "project.cpp"
