// Fused SSIM loss for the CPU: the training-loss SSIM of anigs/ssim/reference.py (11-tap Gaussian window,
// zero-padded 'same' filtering, mean over pixels and channels) with its analytic backward; see
// anigs/ssim/fused.py for the maths. Built and loaded by anigs/ssim/kernel.py.
//
// Images are float32 [B,H,W,C] (channels last, contiguous), so one image row is L = W*C
// interleaved floats and a horizontal tap is a shift by C floats. Per image, in one sweep
// over the rows (blur_rows):
//   forward   horizontal blur of the five maps x, y, x^2, y^2, xy from zero-padded row
//             copies, vertical blur over a ring of the last 11 such rows, then per pixel the
//             SSIM map (summed per row in double) and the three partials A, B, C the
//             backward needs;
//   backward  the same sweep over A, B, C, then gx = scale * (G*A + 2x G*B + y G*C).
// Bands of rows run in parallel (OpenMP when built with it); every sum has a fixed order, so
// results are bit-identical whatever the thread count.
#include <cstring>
#include <vector>
#ifdef _OPENMP
#include <omp.h>
#endif

namespace {
constexpr int WIN = 11;
constexpr int RAD = WIN / 2;

// out[p] = sum_k g[k] * pad[p + k*C] for p in [0, L): the horizontal blur of one padded row.
// Taps innermost (unrolled), pixels vectorised: one store per output.
inline void hblur(const float* __restrict pad, float* __restrict out, int L, int C, const float* __restrict g) {
  float gk[WIN];
  for (int k = 0; k < WIN; ++k) gk[k] = g[k];
  for (int p = 0; p < L; ++p) {
    float s = gk[0] * pad[p];
    for (int k = 1; k < WIN; ++k) s += gk[k] * pad[p + k * C];
    out[p] = s;
  }
}

// out[p] = sum_{k=k0..k1} g[k] * rows[k][p]: the vertical blur of one row from the WIN rows
// around it (rows[k] is image row i + k - RAD; those outside the image are skipped).
inline void vblur(const float* const* rows, float* __restrict out, int L, int k0, int k1,
                  const float* __restrict g) {
  if (k0 == 0 && k1 == WIN - 1) {
    const float *r0 = rows[0], *r1 = rows[1], *r2 = rows[2], *r3 = rows[3], *r4 = rows[4], *r5 = rows[5],
                *r6 = rows[6], *r7 = rows[7], *r8 = rows[8], *r9 = rows[9], *r10 = rows[10];
    const float g0 = g[0], g1 = g[1], g2 = g[2], g3 = g[3], g4 = g[4], g5 = g[5], g6 = g[6], g7 = g[7],
                g8 = g[8], g9 = g[9], g10 = g[10];
    for (int p = 0; p < L; ++p)
      out[p] = g0 * r0[p] + g1 * r1[p] + g2 * r2[p] + g3 * r3[p] + g4 * r4[p] + g5 * r5[p] + g6 * r6[p] +
               g7 * r7[p] + g8 * r8[p] + g9 * r9[p] + g10 * r10[p];
    return;
  }
  for (int p = 0; p < L; ++p) out[p] = g[k0] * rows[k0][p];
  for (int k = k0 + 1; k <= k1; ++k) {
    const float gk = g[k];
    const float* __restrict src = rows[k];
    for (int p = 0; p < L; ++p) out[p] += gk * src[p];
  }
}

// The five padded maps of one row: x, y, x^2, y^2, xy.
inline void fill5(const float* __restrict xr, const float* __restrict yr, float* __restrict p0,
                  float* __restrict p1, float* __restrict p2, float* __restrict p3, float* __restrict p4, int L) {
  for (int p = 0; p < L; ++p) {
    const float xv = xr[p], yv = yr[p];
    p0[p] = xv;
    p1[p] = yv;
    p2[p] = xv * xv;
    p3[p] = yv * yv;
    p4[p] = xv * yv;
  }
}

// SSIM map of one row from its blurred moments; with Ar non-null also the partials
// A = dm/du = 2v (n2 - n1) / (d1 d2) + 2u m (1/d2 - 1/d1), B = dm/dG*(x^2) = -m/d2 and
// C = dm/dG*(xy) = 2 n1 / (d1 d2).
template <bool PARTS>
inline void ssim_row(const float* __restrict mx, const float* __restrict my, const float* __restrict exx,
                     const float* __restrict eyy, const float* __restrict exy, float c1, float c2,
                     float* __restrict mrow, float* __restrict Ar, float* __restrict Br, float* __restrict Cr, int L) {
  for (int p = 0; p < L; ++p) {
    const float mx2 = mx[p] * mx[p], my2 = my[p] * my[p], mxy = mx[p] * my[p];
    const float n1 = 2.0f * mxy + c1;
    const float n2 = 2.0f * (exy[p] - mxy) + c2;
    const float d1 = mx2 + my2 + c1;
    const float d2 = (exx[p] - mx2) + (eyy[p] - my2) + c2;
    const float inv = 1.0f / (d1 * d2);
    const float m = n1 * n2 * inv;
    mrow[p] = m;
    if (PARTS) {
      Ar[p] = (2.0f * my[p] * (n2 - n1) + 2.0f * mx[p] * m * (d1 - d2)) * inv;
      Br[p] = -m * d1 * inv;
      Cr[p] = 2.0f * n1 * inv;
    }
  }
}

// Sum of a row in double with eight fixed-order partial sums.
inline double row_total(const float* v, int L) {
  double acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int p = 0;
  for (; p + 8 <= L; p += 8)
    for (int k = 0; k < 8; ++k) acc[k] += v[p + k];
  for (; p < L; ++p) acc[0] += v[p];
  return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
}

// gx = scale * (bA + 2x bB + y bC) for one row.
inline void grad_row(const float* __restrict ba, const float* __restrict bb, const float* __restrict bc,
                     const float* __restrict xr, const float* __restrict yr, float scale, float* __restrict gr,
                     int L) {
  for (int p = 0; p < L; ++p) gr[p] = scale * (ba[p] + 2.0f * xr[p] * bb[p] + yr[p] * bc[p]);
}

// Blur nmaps maps of one image, [H][L] each, and hand every blurred row to the caller:
// fill(j, pad, PL) writes the zero-padded copies of row j of each map (interior from offset
// RAD*C, PL floats apart), emit(i, out, scratch) receives the nmaps blurred rows i (L floats
// apart) and a scratch row of L floats.
// The rows are cut into one band per thread; a band keeps the horizontally blurred rows it
// needs in a ring of WIN rows per map (cache-resident), so each row is blurred horizontally
// once (plus RAD rows either side of a band boundary) and nothing image-sized is written.
template <typename Fill, typename Emit>
void blur_rows(int H, int W, int C, int nmaps, const float* g, int nthreads, Fill fill, Emit emit) {
  const int L = W * C;
  const int PL = (W + 2 * RAD) * C;
  const int nb = nthreads < H ? (nthreads < 1 ? 1 : nthreads) : H;
#pragma omp parallel for schedule(static, 1) num_threads(nb)
  for (int t = 0; t < nb; ++t) {
    static thread_local std::vector<float> buf;
    const size_t need = (size_t)nmaps * (PL + WIN * L + L) + L;
    if (buf.size() < need) buf.resize(need);
    float* pad = buf.data();
    float* ring = pad + (size_t)nmaps * PL;
    float* out = ring + (size_t)nmaps * WIN * L;
    float* scratch = out + (size_t)nmaps * L;  // one row for emit
    std::memset(pad, 0, sizeof(float) * (size_t)nmaps * PL);  // the borders stay zero
    auto hrow = [&](int j) {
      fill(j, pad, PL);
      for (int q = 0; q < nmaps; ++q) hblur(pad + (size_t)q * PL, ring + ((size_t)q * WIN + j % WIN) * L, L, C, g);
    };
    const int r0 = (int)((long)H * t / nb), r1 = (int)((long)H * (t + 1) / nb);
    for (int j = r0 - RAD < 0 ? 0 : r0 - RAD; j < r0 + RAD && j < H; ++j) hrow(j);
    for (int i = r0; i < r1; ++i) {
      if (i + RAD < H) hrow(i + RAD);
      const int k0 = i - RAD < 0 ? RAD - i : 0;
      const int k1 = i + RAD >= H ? H - 1 - i + RAD : WIN - 1;
      for (int q = 0; q < nmaps; ++q) {
        const float* rows[WIN];
        for (int k = k0; k <= k1; ++k) rows[k] = ring + ((size_t)q * WIN + (i + k - RAD) % WIN) * L;
        vblur(rows, out + (size_t)q * L, L, k0, k1, g);
      }
      emit(i, out, scratch);
    }
  }
}
}  // namespace

extern "C" {

int anigs_ssim_abi_version() { return 1; }

// Forward. x, y [B,H,W,C]; g[11] the window. A, Bm, Cm [B,H,W,C] (the partials of the SSIM map
// with respect to G*x, G*(x^2) and G*(xy)) are written when A is not null. Returns the sum of
// the SSIM map over all B*H*W*C entries (per-row sums in double, added in row order).
double anigs_ssim_forward(int B, int H, int W, int C, const float* x, const float* y, const float* g, float c1,
                          float c2, float* A, float* Bm, float* Cm, int nthreads) {
  const int L = W * C;
  const size_t plane = (size_t)H * L;
  std::vector<double> row_sum((size_t)B * H, 0.0);
  for (int b = 0; b < B; ++b) {
    const float* xb = x + b * plane;
    const float* yb = y + b * plane;
    auto fill = [&](int i, float* pad, int PL) {
      float* p0 = pad + RAD * C;
      fill5(xb + (size_t)i * L, yb + (size_t)i * L, p0, p0 + PL, p0 + 2 * PL, p0 + 3 * PL, p0 + 4 * PL, L);
    };
    auto emit = [&](int i, const float* v, float* mrow) {
      const size_t off = b * plane + (size_t)i * L;
      if (A)
        ssim_row<true>(v, v + L, v + 2 * L, v + 3 * L, v + 4 * L, c1, c2, mrow, A + off, Bm + off, Cm + off, L);
      else
        ssim_row<false>(v, v + L, v + 2 * L, v + 3 * L, v + 4 * L, c1, c2, mrow, nullptr, nullptr, nullptr, L);
      row_sum[(size_t)b * H + i] = row_total(mrow, L);
    };
    blur_rows(H, W, C, 5, g, nthreads, fill, emit);
  }
  double total = 0.0;
  for (double s : row_sum) total += s;
  return total;
}

// Backward: gx = scale * (G*A + 2x G*Bm + y G*Cm), all [B,H,W,C].
void anigs_ssim_backward(int B, int H, int W, int C, const float* x, const float* y, const float* g,
                         const float* A, const float* Bm, const float* Cm, float scale, float* gx, int nthreads) {
  const int L = W * C;
  const size_t plane = (size_t)H * L;
  for (int b = 0; b < B; ++b) {
    const size_t ob = b * plane;
    auto fill = [&](int i, float* pad, int PL) {
      const size_t off = ob + (size_t)i * L;
      std::memcpy(pad + RAD * C, A + off, sizeof(float) * L);
      std::memcpy(pad + PL + RAD * C, Bm + off, sizeof(float) * L);
      std::memcpy(pad + 2 * PL + RAD * C, Cm + off, sizeof(float) * L);
    };
    auto emit = [&](int i, const float* v, float*) {
      const size_t off = ob + (size_t)i * L;
      grad_row(v, v + L, v + 2 * L, x + off, y + off, scale, gx + off, L);
    };
    blur_rows(H, W, C, 3, g, nthreads, fill, emit);
  }
}

}  // extern "C"
