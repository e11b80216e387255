// Per-Gaussian preprocessing for the CPU rasterizer, forward and analytic backward:
// EWA projection (mirrors anigs/render/projection.py, the reference) fused with the
// view-dependent colour (mirrors anigs/geometry/sh.py, degrees 0-3) and input validation.
// Gradients flow to means, quats, scales and colours/SH (cameras are fixed).
// Included by raster.cpp into one library.
#include <cmath>
#include <algorithm>

namespace proj {

struct Cam {
  float R[9], t[3], fx, fy, cx, cy;
  int W, H;
  float near, far, eps2d;
  float lxp, lxn, lyp, lyn;  // view-direction clamp (per camera, see forward_one)
  float campos[3];  // camera centre in world space, -R^T t (SH view directions)
};

// cam: [R(9), t(3), fx, fy, cx, cy, near, far, eps2d]
inline Cam unpack(const float* cam, int W, int H) {
  Cam c;
  for (int i = 0; i < 9; ++i) c.R[i] = cam[i];
  for (int i = 0; i < 3; ++i) c.t[i] = cam[9 + i];
  c.fx = cam[12]; c.fy = cam[13]; c.cx = cam[14]; c.cy = cam[15];
  c.near = cam[16]; c.far = cam[17]; c.eps2d = cam[18]; c.W = W; c.H = H;
  for (int i = 0; i < 3; ++i)
    c.campos[i] = -(c.R[i] * c.t[0] + c.R[3 + i] * c.t[1] + c.R[6 + i] * c.t[2]);
  const float tanx = 0.5f * c.W / c.fx, tany = 0.5f * c.H / c.fy;
  c.lxp = (c.W - c.cx) / c.fx + 0.3f * tanx; c.lxn = c.cx / c.fx + 0.3f * tanx;
  c.lyp = (c.H - c.cy) / c.fy + 0.3f * tany; c.lyn = c.cy / c.fy + 0.3f * tany;
  return c;
}

// The projection is written once for a lane type T: float (one Gaussian) or vf16 (16
// Gaussians at a time). Lanes compute exactly what the scalar code computes (same
// operations in the same order; -ffp-contract=off), branches become selects.
template <class T> struct Lanes;
template <> struct Lanes<float> {
  typedef bool M;
  static ANIGS_INLINE float bc(float x) { return x; }
  static ANIGS_INLINE float sel(bool m, float a, float b) { return m ? a : b; }
  static ANIGS_INLINE float sqrt(float x) { return std::sqrt(x); }
};
template <> struct Lanes<vf16> {
  typedef vi16 M;
  static ANIGS_INLINE vf16 bc(float x) { return vf16{} + x; }
  static ANIGS_INLINE vf16 sel(vi16 m, vf16 a, vf16 b) { return ::sel(m, a, b); }
  static ANIGS_INLINE vf16 sqrt(vf16 x) {
#if defined(__AVX512F__)
    return (vf16)_mm512_sqrt_ps((__m512)x);
#else
    vf16 r;
    for (int i = 0; i < 16; ++i) r[i] = std::sqrt(x[i]);
    return r;
#endif
  }
};
template <> struct Lanes<vf8> {
  typedef vi8 M;
  static ANIGS_INLINE vf8 bc(float x) { return vf8{} + x; }
  static ANIGS_INLINE vf8 sel(vi8 m, vf8 a, vf8 b) { return ::sel(m, a, b); }
  static ANIGS_INLINE vf8 sqrt(vf8 x) {
#if defined(__AVX__)
    return (vf8)_mm256_sqrt_ps((__m256)x);
#else
    vf8 r;
    for (int i = 0; i < 8; ++i) r[i] = std::sqrt(x[i]);
    return r;
#endif
  }
};
template <> struct Lanes<vf4> {
  typedef vi4 M;
  static ANIGS_INLINE vf4 bc(float x) { return vf4{} + x; }
  static ANIGS_INLINE vf4 sel(vi4 m, vf4 a, vf4 b) { return ::sel(m, a, b); }
  static ANIGS_INLINE vf4 sqrt(vf4 x) {
#if defined(__SSE__)
    return (vf4)_mm_sqrt_ps((__m128)x);
#else
    vf4 r;
    for (int i = 0; i < 4; ++i) r[i] = std::sqrt(x[i]);
    return r;
#endif
  }
};
// Gaussians per batch: one hardware vector (16 lanes with AVX-512, 8 with AVX, else 4).
#if defined(__AVX512F__)
typedef vf16 PV;
#elif defined(__AVX__)
typedef vf8 PV;
#else
typedef vf4 PV;
#endif
constexpr int PL = sizeof(PV) / sizeof(float);
// max(x, lo) and min(x, hi) as std::max / std::min (NaN-propagating the same way).
template <class T> ANIGS_INLINE T tmax(T x, float lo) { return Lanes<T>::sel(x < lo, Lanes<T>::bc(lo), x); }
template <class T> ANIGS_INLINE T tmin(T x, float hi) { return Lanes<T>::sel(hi < x, Lanes<T>::bc(hi), x); }

// Forward intermediates of the projection, recomputed in the backward.
template <class T> struct Fwd {
  typedef typename Lanes<T>::M M;
  T qn[4], qnorm, Rq[9], M_[9], Sig[9], pc[3], u, v, J[6], Tm[6], cov[3], det;
  M uclamped, vclamped, valid;
};

// mu [3], q [4], s [3]: one value (or 16 lanes) per component.
template <class T> ANIGS_INLINE void forward_one(const Cam& c, const T* mu, const T* q, const T* s, Fwd<T>& f) {
  typedef Lanes<T> L;
  const T n = L::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  f.qnorm = n;
  const T d = tmax(n, 1e-12f);
  for (int i = 0; i < 4; ++i) f.qn[i] = q[i] / d;
  {
    const T w = f.qn[0], x = f.qn[1], y = f.qn[2], z = f.qn[3];
    T* R = f.Rq;
    R[0] = 1.f - 2.f * (y * y + z * z); R[1] = 2.f * (x * y - w * z); R[2] = 2.f * (x * z + w * y);
    R[3] = 2.f * (x * y + w * z); R[4] = 1.f - 2.f * (x * x + z * z); R[5] = 2.f * (y * z - w * x);
    R[6] = 2.f * (x * z - w * y); R[7] = 2.f * (y * z + w * x); R[8] = 1.f - 2.f * (x * x + y * y);
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) f.M_[3 * i + j] = f.Rq[3 * i + j] * s[j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      f.Sig[3 * i + j] = f.M_[3 * i] * f.M_[3 * j] + f.M_[3 * i + 1] * f.M_[3 * j + 1] + f.M_[3 * i + 2] * f.M_[3 * j + 2];
  for (int i = 0; i < 3; ++i)
    f.pc[i] = c.R[3 * i] * mu[0] + c.R[3 * i + 1] * mu[1] + c.R[3 * i + 2] * mu[2] + c.t[i];
  const T z = f.pc[2];
  f.valid = (z > c.near) & (z < c.far);
  const T zs = L::sel(f.valid, z, L::bc(1.f));
  const float lxp = c.lxp, lxn = c.lxn, lyp = c.lyp, lyn = c.lyn;
  const T ux = f.pc[0] / zs, vy = f.pc[1] / zs;
  f.u = tmin(tmax(ux, -lxn), lxp);
  f.v = tmin(tmax(vy, -lyn), lyp);
  f.uclamped = (ux < -lxn) | (ux > lxp);
  f.vclamped = (vy < -lyn) | (vy > lyp);
  // J = [[fx/z, 0, -fx u/z], [0, fy/z, -fy v/z]]
  f.J[0] = c.fx / zs; f.J[1] = L::bc(0.f); f.J[2] = -c.fx * (zs * f.u) / (zs * zs);
  f.J[3] = L::bc(0.f); f.J[4] = c.fy / zs; f.J[5] = -c.fy * (zs * f.v) / (zs * zs);
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      f.Tm[3 * i + j] = f.J[3 * i] * c.R[j] + f.J[3 * i + 1] * c.R[3 + j] + f.J[3 * i + 2] * c.R[6 + j];
  T TS[6];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      TS[3 * i + j] = f.Tm[3 * i] * f.Sig[j] + f.Tm[3 * i + 1] * f.Sig[3 + j] + f.Tm[3 * i + 2] * f.Sig[6 + j];
  f.cov[0] = TS[0] * f.Tm[0] + TS[1] * f.Tm[1] + TS[2] * f.Tm[2] + c.eps2d;
  f.cov[1] = TS[0] * f.Tm[3] + TS[1] * f.Tm[4] + TS[2] * f.Tm[5];
  f.cov[2] = TS[3] * f.Tm[3] + TS[4] * f.Tm[4] + TS[5] * f.Tm[5] + c.eps2d;
  f.det = f.cov[0] * f.cov[2] - f.cov[1] * f.cov[1];
  f.valid = f.valid & (f.det > 0.f) & ((f.det - f.det) == 0.f);  // det finite
}

// Gradients w.r.t. mean, quat, scale from grads of means2d (gm0, gm1), conic (gA, gB, gC)
// and depth, given the forward intermediates f (only meaningful where f.valid).
template <class T>
ANIGS_INLINE void backward_one(const Cam& c, const Fwd<T>& f, const T* s, T gm0, T gm1, T gA, T gB, T gC, T gdep,
                         T* gm, T* gq, T* gs) {
  typedef Lanes<T> L;
  const T z = f.pc[2], x = f.pc[0], y = f.pc[1];
  const T a = f.cov[0], b = f.cov[1], cc = f.cov[2], det = f.det, det2 = det * det;
  // conic (A,B,C) = (c, -b, a) / det  ->  grads w.r.t. the 2D covariance entries
  const T ga = gA * (-cc * cc / det2) + gB * (b * cc / det2) + gC * (-b * b / det2);
  const T gb = gA * (2.f * b * cc / det2) + gB * (-1.f / det - 2.f * b * b / det2) + gC * (2.f * a * b / det2);
  const T gc = gA * (-b * b / det2) + gB * (a * b / det2) + gC * (-a * a / det2);
  const T G[4] = {ga, 0.5f * gb, 0.5f * gb, gc};  // symmetric 2x2 gradient
  // cov2 = T Sig T^T: G_Sig = T^T G T, G_T = 2 G T Sig
  T GT[6], TS[6], GSig[9];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j) GT[3 * i + j] = G[2 * i] * f.Tm[j] + G[2 * i + 1] * f.Tm[3 + j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) GSig[3 * i + j] = f.Tm[i] * GT[j] + f.Tm[3 + i] * GT[3 + j];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      TS[3 * i + j] = f.Tm[3 * i] * f.Sig[j] + f.Tm[3 * i + 1] * f.Sig[3 + j] + f.Tm[3 * i + 2] * f.Sig[6 + j];
  T GTm[6];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j) GTm[3 * i + j] = 2.f * (G[2 * i] * TS[j] + G[2 * i + 1] * TS[3 + j]);
  // T = J Rv: G_J = G_T Rv^T
  T GJ[6];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      GJ[3 * i + j] = GTm[3 * i] * c.R[3 * j] + GTm[3 * i + 1] * c.R[3 * j + 1] + GTm[3 * i + 2] * c.R[3 * j + 2];
  // J entries: J00 = fx/z, J02 = -fx u / z, J11 = fy/z, J12 = -fy v / z, u = clamp(x/z)
  const T zero = L::bc(0.f);
  T gx = zero, gy = zero, gz = zero;
  const T z2 = z * z, z3 = z2 * z;
  gz += GJ[0] * (-c.fx / z2) + GJ[4] * (-c.fy / z2);
  gz += L::sel(f.uclamped, GJ[2] * (c.fx * f.u / z2), GJ[2] * (2.f * c.fx * x / z3));
  gx += L::sel(f.uclamped, zero, GJ[2] * (-c.fx / z2));
  gz += L::sel(f.vclamped, GJ[5] * (c.fy * f.v / z2), GJ[5] * (2.f * c.fy * y / z3));
  gy += L::sel(f.vclamped, zero, GJ[5] * (-c.fy / z2));
  // means2d = (fx x/z + cx, fy y/z + cy); depth = z
  gx += gm0 * c.fx / z;
  gy += gm1 * c.fy / z;
  gz += -gm0 * c.fx * x / z2 - gm1 * c.fy * y / z2 + gdep;
  // pc = Rv mu + t
  for (int j = 0; j < 3; ++j) gm[j] = c.R[j] * gx + c.R[3 + j] * gy + c.R[6 + j] * gz;
  // Sig = M M^T (G_Sig symmetric): G_M = 2 G_Sig M;  M = Rq diag(s)
  T GM[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      GM[3 * i + j] = 2.f * (GSig[3 * i] * f.M_[j] + GSig[3 * i + 1] * f.M_[3 + j] + GSig[3 * i + 2] * f.M_[6 + j]);
  T GR[9];
  gs[0] = gs[1] = gs[2] = zero;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      gs[j] += GM[3 * i + j] * f.Rq[3 * i + j];
      GR[3 * i + j] = GM[3 * i + j] * s[j];
    }
  const T w = f.qn[0], qx = f.qn[1], qy = f.qn[2], qz = f.qn[3];
  T gqn[4];
  gqn[0] = 2.f * (-qz * GR[1] + qy * GR[2] + qz * GR[3] - qx * GR[5] - qy * GR[6] + qx * GR[7]);
  gqn[1] = 2.f * (qy * GR[1] + qz * GR[2] + qy * GR[3] - 2.f * qx * GR[4] - w * GR[5] + qz * GR[6] + w * GR[7] - 2.f * qx * GR[8]);
  gqn[2] = 2.f * (-2.f * qy * GR[0] + qx * GR[1] + w * GR[2] + qx * GR[3] + qz * GR[5] - w * GR[6] + qz * GR[7] - 2.f * qy * GR[8]);
  gqn[3] = 2.f * (-2.f * qz * GR[0] - w * GR[1] + qx * GR[2] + w * GR[3] - 2.f * qz * GR[4] + qy * GR[5] + qx * GR[6] + qy * GR[7]);
  // qn = q / max(|q|, eps)
  const T dot = gqn[0] * w + gqn[1] * qx + gqn[2] * qy + gqn[3] * qz;
  const auto big = f.qnorm > 1e-12f;
  for (int i = 0; i < 4; ++i) gq[i] = L::sel(big, (gqn[i] - f.qn[i] * dot) / f.qnorm, gqn[i] / 1e-12f);
}

// PL consecutive Gaussians g0 .. g0+PL-1 as lanes (indices past N repeat the last one).
inline void gather(const float* a, int stride, int comps, int g0, int N, PV* out) {
  for (int l = 0; l < PL; ++l) {
    const float* p = a + (size_t)stride * std::min(g0 + l, N - 1);
    for (int k = 0; k < comps; ++k) out[k][l] = p[k];
  }
}

// ---- spherical harmonics (anigs/geometry/sh.py: same basis, signs and operation order) ----
constexpr float SH_C0 = 0.28209479177387814f;
constexpr float SH_C1 = 0.4886025119029199f;
constexpr float SH_C2[5] = {1.0925484305920792f, -1.0925484305920792f, 0.31539156525252005f,
                            -1.0925484305920792f, 0.5462742152960396f};
constexpr float SH_C3[7] = {-0.5900435899266435f, 2.890611442640554f, -0.4570457994644658f, 0.3731763325901154f,
                            -0.4570457994644658f, 1.445305721320277f, -0.5900435899266435f};

// Basis values b[k] (k < (deg+1)^2) along the unit direction d.
inline void sh_basis(int deg, const float* d, float* b) {
  b[0] = SH_C0;
  if (deg < 1) return;
  const float x = d[0], y = d[1], z = d[2];
  b[1] = -SH_C1 * y; b[2] = SH_C1 * z; b[3] = -SH_C1 * x;
  if (deg < 2) return;
  const float xx = x * x, yy = y * y, zz = z * z, xy = x * y, yz = y * z, xz = x * z;
  b[4] = SH_C2[0] * xy; b[5] = SH_C2[1] * yz; b[6] = SH_C2[2] * (2.f * zz - xx - yy);
  b[7] = SH_C2[3] * xz; b[8] = SH_C2[4] * (xx - yy);
  if (deg < 3) return;
  b[9] = SH_C3[0] * y * (3.f * xx - yy); b[10] = SH_C3[1] * xy * z; b[11] = SH_C3[2] * y * (4.f * zz - xx - yy);
  b[12] = SH_C3[3] * z * (2.f * zz - 3.f * xx - 3.f * yy); b[13] = SH_C3[4] * x * (4.f * zz - xx - yy);
  b[14] = SH_C3[5] * z * (xx - yy); b[15] = SH_C3[6] * x * (xx - 3.f * yy);
}

// d b[k] / d (x, y, z) for k >= 1, as db[3k .. 3k+2].
inline void sh_basis_grad(int deg, const float* d, float* db) {
  const float x = d[0], y = d[1], z = d[2];
  for (int i = 0; i < 48; ++i) db[i] = 0.f;
  if (deg < 1) return;
  db[3 * 1 + 1] = -SH_C1; db[3 * 2 + 2] = SH_C1; db[3 * 3 + 0] = -SH_C1;
  if (deg < 2) return;
  const float xx = x * x, yy = y * y, zz = z * z;
  db[3 * 4 + 0] = SH_C2[0] * y; db[3 * 4 + 1] = SH_C2[0] * x;
  db[3 * 5 + 1] = SH_C2[1] * z; db[3 * 5 + 2] = SH_C2[1] * y;
  db[3 * 6 + 0] = SH_C2[2] * -2.f * x; db[3 * 6 + 1] = SH_C2[2] * -2.f * y; db[3 * 6 + 2] = SH_C2[2] * 4.f * z;
  db[3 * 7 + 0] = SH_C2[3] * z; db[3 * 7 + 2] = SH_C2[3] * x;
  db[3 * 8 + 0] = SH_C2[4] * 2.f * x; db[3 * 8 + 1] = SH_C2[4] * -2.f * y;
  if (deg < 3) return;
  db[3 * 9 + 0] = SH_C3[0] * 6.f * x * y; db[3 * 9 + 1] = SH_C3[0] * (3.f * xx - 3.f * yy);
  db[3 * 10 + 0] = SH_C3[1] * y * z; db[3 * 10 + 1] = SH_C3[1] * x * z; db[3 * 10 + 2] = SH_C3[1] * x * y;
  db[3 * 11 + 0] = SH_C3[2] * -2.f * x * y; db[3 * 11 + 1] = SH_C3[2] * (4.f * zz - xx - 3.f * yy);
  db[3 * 11 + 2] = SH_C3[2] * 8.f * y * z;
  db[3 * 12 + 0] = SH_C3[3] * -6.f * x * z; db[3 * 12 + 1] = SH_C3[3] * -6.f * y * z;
  db[3 * 12 + 2] = SH_C3[3] * (6.f * zz - 3.f * xx - 3.f * yy);
  db[3 * 13 + 0] = SH_C3[4] * (4.f * zz - 3.f * xx - yy); db[3 * 13 + 1] = SH_C3[4] * -2.f * x * y;
  db[3 * 13 + 2] = SH_C3[4] * 8.f * x * z;
  db[3 * 14 + 0] = SH_C3[5] * 2.f * x * z; db[3 * 14 + 1] = SH_C3[5] * -2.f * y * z;
  db[3 * 14 + 2] = SH_C3[5] * (xx - yy);
  db[3 * 15 + 0] = SH_C3[6] * (3.f * xx - 3.f * yy); db[3 * 15 + 1] = SH_C3[6] * -6.f * x * y;
}

// Unit view direction (camera -> mean) as torch's F.normalize(eps=1e-12); returns the norm.
inline float view_dir(const Cam& c, const float* mu, float* d) {
  const float v[3] = {mu[0] - c.campos[0], mu[1] - c.campos[1], mu[2] - c.campos[2]};
  const float n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  const float dn = std::max(n, 1e-12f);
  for (int i = 0; i < 3; ++i) d[i] = v[i] / dn;
  return n;
}

// Raw SH value (before +0.5 and the clamp) of the 3 channels; sh is [K,3].
inline void sh_eval(int deg, const float* sh, const float* d, float* raw) {
  float b[16];
  sh_basis(deg, d, b);
  const int nk = (deg + 1) * (deg + 1);
  for (int ch = 0; ch < 3; ++ch) {
    float acc = b[0] * sh[ch];
    for (int k = 1; k < nk; ++k) acc += b[k] * sh[3 * k + ch];
    raw[ch] = acc;
  }
}

}  // namespace proj

extern "C" {

// Validation flags returned by anigs_preprocess (the caller turns them into messages).
// 1 means, 2 quats, 4 scales, 8 opacities, 16 colours: non-finite; 32 scales < 0; 64 opacity outside [0,1].

// Per-Gaussian forward: projection, colour and (check != 0) input validation.
// colors: [N,3] raw colours when deg < 0, else SH [N,K,3] evaluated to max(SH(dir) + 0.5, 0).
// feats [N,4] out: (r, g, b, depth). Colours are only computed for valid Gaussians.
int anigs_preprocess(int N, const float* cam, int W, int H, const float* means, const float* quats,
                     const float* scales, const float* opac, const float* colors, int K, int deg,
                     float* means2d, float* conics, float* feats, int* rects, int* radii,
                     unsigned char* valid, int check, int nthreads) {
  const proj::Cam c = proj::unpack(cam, W, H);
  std::atomic<int> all_flags{0};
  const int ncol = deg < 0 ? 3 : 3 * K;
  pool::parallel_for((N + proj::PL - 1) / proj::PL, nthreads_or_max(nthreads), 1024 / proj::PL, [&](int bb, int be) {
  int flags = 0;
  for (int blk = bb; blk < be; ++blk) {
  const int g0 = proj::PL * blk;
  proj::PV mu[3], q[4], s[3];
  proj::gather(means, 3, 3, g0, N, mu);
  proj::gather(quats, 4, 4, g0, N, q);
  proj::gather(scales, 3, 3, g0, N, s);
  proj::Fwd<proj::PV> fv;
  proj::forward_one(c, mu, q, s, fv);
  typedef proj::PV PV;
  const PV zsv = sel((fv.pc[2] > c.near) & (fv.pc[2] < c.far), fv.pc[2], bc<PV>(1.f));
  const PV mxv = c.fx * fv.pc[0] / zsv + c.cx, myv = c.fy * fv.pc[1] / zsv + c.cy;
  const PV dsv = sel(fv.valid, fv.det, bc<PV>(1.f));
  const PV Av = fv.cov[2] / dsv, Bv = -fv.cov[1] / dsv, Cv = fv.cov[0] / dsv;
  for (int l = 0; l < proj::PL && g0 + l < N; ++l) {
    const int g = g0 + l;
    if (check) {
      const float* mu = means + 3 * g; const float* q = quats + 4 * g; const float* s = scales + 3 * g;
      const float* col = colors + (size_t)ncol * g;
      if (!(std::isfinite(mu[0]) && std::isfinite(mu[1]) && std::isfinite(mu[2]))) flags |= 1;
      if (!(std::isfinite(q[0]) && std::isfinite(q[1]) && std::isfinite(q[2]) && std::isfinite(q[3]))) flags |= 2;
      if (!(std::isfinite(s[0]) && std::isfinite(s[1]) && std::isfinite(s[2]))) flags |= 4;
      if (!std::isfinite(opac[g])) flags |= 8;
      for (int i = 0; i < ncol; ++i)
        if (!std::isfinite(col[i])) flags |= 16;
      if (s[0] < 0.f || s[1] < 0.f || s[2] < 0.f) flags |= 32;
      if (opac[g] < 0.f || opac[g] > 1.f) flags |= 64;
    }
    struct {
      float pc[3], cov[3];
      bool valid;
    } f = {{fv.pc[0][l], fv.pc[1][l], fv.pc[2][l]}, {fv.cov[0][l], fv.cov[1][l], fv.cov[2][l]}, fv.valid[l] != 0};
    const float mx = mxv[l], my = myv[l], A = Av[l], B = Bv[l], C = Cv[l];
    bool ok = f.valid && std::isfinite(mx) && std::isfinite(my) && std::isfinite(A) && std::isfinite(B) &&
              std::isfinite(C) && opac[g] >= 1.f / 255.f;
    means2d[2 * g] = mx; means2d[2 * g + 1] = my;
    conics[3 * g] = A; conics[3 * g + 1] = B; conics[3 * g + 2] = C;
    float* ft = feats + 4 * g;
    ft[0] = ft[1] = ft[2] = 0.f;
    ft[3] = f.pc[2];
    int* r = rects + 4 * g;
    r[0] = r[1] = r[2] = r[3] = 0;
    radii[g] = 0;
    if (ok) {
      const float level = 2.f * std::log(std::max(opac[g] * 255.f, 1.f));
      const float ex = std::min(std::sqrt(level * std::max(f.cov[0], 0.f)), 1e7f);
      const float ey = std::min(std::sqrt(level * std::max(f.cov[2], 0.f)), 1e7f);
      const float cmx = std::min(std::max(mx, -1e7f), 1e7f), cmy = std::min(std::max(my, -1e7f), 1e7f);
      const float x0 = std::min(std::max(std::ceil(cmx - ex - 0.5f), 0.f), float(W));
      const float x1 = std::min(std::max(std::floor(cmx + ex - 0.5f) + 1.f, 0.f), float(W));
      const float y0 = std::min(std::max(std::ceil(cmy - ey - 0.5f), 0.f), float(H));
      const float y1 = std::min(std::max(std::floor(cmy + ey - 0.5f) + 1.f, 0.f), float(H));
      ok = x1 > x0 && y1 > y0;
      if (ok) {
        r[0] = int(x0); r[1] = int(y0); r[2] = int(x1); r[3] = int(y1);
        radii[g] = int(std::ceil(std::max(ex, ey)));
      }
    }
    valid[g] = ok ? 1 : 0;
    if (!ok) continue;
    if (deg < 0) {
      for (int ch = 0; ch < 3; ++ch) ft[ch] = colors[3 * g + ch];
    } else if (deg == 0) {
      const float* sh = colors + (size_t)3 * K * g;
      for (int ch = 0; ch < 3; ++ch) ft[ch] = std::max(proj::SH_C0 * sh[ch] + 0.5f, 0.f);
    } else {
      float d[3], raw[3];
      proj::view_dir(c, means + 3 * g, d);
      proj::sh_eval(deg, colors + (size_t)3 * K * g, d, raw);
      for (int ch = 0; ch < 3; ++ch) ft[ch] = std::max(raw[ch] + 0.5f, 0.f);
    }
  }
  }
  all_flags.fetch_or(flags, std::memory_order_relaxed);
  });
  return all_flags.load();
}

// Backward of anigs_preprocess. Upstream grads (any may be null = zero): g_means2d [N,2],
// g_conics [N,3], g_feats [N,4] (colour and depth). Writes every entry of g_means [N,3],
// g_quats [N,4], g_scales [N,3] and g_colors (same shape as colors; zero where unused).
void anigs_preprocess_backward(int N, const float* cam, int W, int H, const float* means, const float* quats,
                               const float* scales, const float* colors, int K, int deg,
                               const unsigned char* valid, const float* g_means2d, const float* g_conics,
                               const float* g_feats, float* g_means, float* g_quats, float* g_scales,
                               float* g_colors, int nthreads) {
  const proj::Cam c = proj::unpack(cam, W, H);
  const int ncol = deg < 0 ? 3 : 3 * K;
  pool::parallel_for((N + proj::PL - 1) / proj::PL, nthreads_or_max(nthreads), 1024 / proj::PL, [&](int bb, int be) {
  for (int blk = bb; blk < be; ++blk) {
  const int g0 = proj::PL * blk;
  proj::PV mu[3], q[4], s[3], gm2[2] = {}, gcon[3] = {}, gdep = {};
  proj::gather(means, 3, 3, g0, N, mu);
  proj::gather(quats, 4, 4, g0, N, q);
  proj::gather(scales, 3, 3, g0, N, s);
  if (g_means2d) proj::gather(g_means2d, 2, 2, g0, N, gm2);
  if (g_conics) proj::gather(g_conics, 3, 3, g0, N, gcon);
  if (g_feats) proj::gather(g_feats + 3, 4, 1, g0, N, &gdep);
  proj::Fwd<proj::PV> fv;
  proj::forward_one(c, mu, q, s, fv);
  proj::PV gmv[3], gqv[4], gsv[3];
  proj::backward_one(c, fv, s, gm2[0], gm2[1], gcon[0], gcon[1], gcon[2], gdep, gmv, gqv, gsv);
  for (int l = 0; l < proj::PL && g0 + l < N; ++l) {
    const int g = g0 + l;
    float* gm = g_means + 3 * g;
    float* gq = g_quats + 4 * g;
    float* gs = g_scales + 3 * g;
    float* gcol = g_colors + (size_t)ncol * g;
    for (int i = 0; i < ncol; ++i) gcol[i] = 0.f;
    if (!valid[g]) {
      gm[0] = gm[1] = gm[2] = 0.f;
      gq[0] = gq[1] = gq[2] = gq[3] = 0.f;
      gs[0] = gs[1] = gs[2] = 0.f;
      continue;
    }
    for (int i = 0; i < 3; ++i) gm[i] = gmv[i][l];
    for (int i = 0; i < 4; ++i) gq[i] = gqv[i][l];
    for (int i = 0; i < 3; ++i) gs[i] = gsv[i][l];
    if (!g_feats) continue;
    const float* gf = g_feats + 4 * g;
    if (deg < 0) {
      for (int ch = 0; ch < 3; ++ch) gcol[ch] = gf[ch];
      continue;
    }
    const float* sh = colors + (size_t)3 * K * g;
    float d[3] = {0.f, 0.f, 0.f}, raw[3], graw[3];
    float n = 0.f;
    if (deg == 0) {
      for (int ch = 0; ch < 3; ++ch) raw[ch] = proj::SH_C0 * sh[ch];
    } else {
      n = proj::view_dir(c, means + 3 * g, d);
      proj::sh_eval(deg, sh, d, raw);
    }
    // colour = max(raw + 0.5, 0): torch's clamp_min passes the gradient where raw + 0.5 >= 0
    for (int ch = 0; ch < 3; ++ch) graw[ch] = (raw[ch] + 0.5f >= 0.f) ? gf[ch] : 0.f;
    if (deg == 0) {
      for (int ch = 0; ch < 3; ++ch) gcol[ch] = proj::SH_C0 * graw[ch];
      continue;
    }
    float b[16], db[48];
    proj::sh_basis(deg, d, b);
    proj::sh_basis_grad(deg, d, db);
    const int nk = (deg + 1) * (deg + 1);
    float gd[3] = {0.f, 0.f, 0.f};
    for (int k = 0; k < nk; ++k) {
      float gk = 0.f;  // sum_ch graw[ch] * sh[k][ch]
      for (int ch = 0; ch < 3; ++ch) {
        gcol[3 * k + ch] = graw[ch] * b[k];
        gk += graw[ch] * sh[3 * k + ch];
      }
      for (int i = 0; i < 3; ++i) gd[i] += gk * db[3 * k + i];
    }
    // d = v / max(|v|, eps), v = mean - campos
    float gv[3];
    if (n > 1e-12f) {
      const float dot = gd[0] * d[0] + gd[1] * d[1] + gd[2] * d[2];
      for (int i = 0; i < 3; ++i) gv[i] = (gd[i] - d[i] * dot) / n;
    } else {
      for (int i = 0; i < 3; ++i) gv[i] = gd[i] / 1e-12f;
    }
    for (int i = 0; i < 3; ++i) gm[i] += gv[i];
  }
  }
  });
}

}  // extern "C"
