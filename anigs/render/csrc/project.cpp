// Fused EWA projection of 3D Gaussians (forward + analytic backward) for the CPU.
// Mirrors anigs/render/projection.py (the reference); gradients flow to means, quats
// and scales (cameras are fixed). Included by raster.cpp into one library.
#include <cmath>
#include <algorithm>

namespace proj {

struct Cam {
  float R[9], t[3], fx, fy, cx, cy;
  int W, H;
  float near, far, eps2d;
};

inline void quat_to_rot(const float* qn, float* R) {
  const float w = qn[0], x = qn[1], y = qn[2], z = qn[3];
  R[0] = 1.f - 2.f * (y * y + z * z); R[1] = 2.f * (x * y - w * z); R[2] = 2.f * (x * z + w * y);
  R[3] = 2.f * (x * y + w * z); R[4] = 1.f - 2.f * (x * x + z * z); R[5] = 2.f * (y * z - w * x);
  R[6] = 2.f * (x * z - w * y); R[7] = 2.f * (y * z + w * x); R[8] = 1.f - 2.f * (x * x + y * y);
}

// cam: [R(9), t(3), fx, fy, cx, cy, near, far, eps2d]
inline Cam unpack(const float* cam, int W, int H) {
  Cam c;
  for (int i = 0; i < 9; ++i) c.R[i] = cam[i];
  for (int i = 0; i < 3; ++i) c.t[i] = cam[9 + i];
  c.fx = cam[12]; c.fy = cam[13]; c.cx = cam[14]; c.cy = cam[15];
  c.near = cam[16]; c.far = cam[17]; c.eps2d = cam[18]; c.W = W; c.H = H;
  return c;
}

// Forward intermediates of one Gaussian, recomputed in the backward.
struct Fwd {
  float qn[4], qnorm, Rq[9], M[9], Sig[9], pc[3], u, v, uclamped, vclamped, J[6], T[6], cov[3], det;
  bool valid;
};

inline void forward_one(const Cam& c, const float* mu, const float* q, const float* s, Fwd& f) {
  float n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  f.qnorm = n;
  const float d = std::max(n, 1e-12f);
  for (int i = 0; i < 4; ++i) f.qn[i] = q[i] / d;
  quat_to_rot(f.qn, f.Rq);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) f.M[3 * i + j] = f.Rq[3 * i + j] * s[j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      f.Sig[3 * i + j] = f.M[3 * i] * f.M[3 * j] + f.M[3 * i + 1] * f.M[3 * j + 1] + f.M[3 * i + 2] * f.M[3 * j + 2];
  for (int i = 0; i < 3; ++i)
    f.pc[i] = c.R[3 * i] * mu[0] + c.R[3 * i + 1] * mu[1] + c.R[3 * i + 2] * mu[2] + c.t[i];
  const float z = f.pc[2];
  f.valid = (z > c.near) && (z < c.far);
  const float zs = f.valid ? z : 1.f;
  const float tanx = 0.5f * c.W / c.fx, tany = 0.5f * c.H / c.fy;
  const float lxp = (c.W - c.cx) / c.fx + 0.3f * tanx, lxn = c.cx / c.fx + 0.3f * tanx;
  const float lyp = (c.H - c.cy) / c.fy + 0.3f * tany, lyn = c.cy / c.fy + 0.3f * tany;
  const float ux = f.pc[0] / zs, vy = f.pc[1] / zs;
  f.u = std::min(std::max(ux, -lxn), lxp);
  f.v = std::min(std::max(vy, -lyn), lyp);
  f.uclamped = (ux < -lxn || ux > lxp) ? 1.f : 0.f;
  f.vclamped = (vy < -lyn || vy > lyp) ? 1.f : 0.f;
  // J = [[fx/z, 0, -fx u/z], [0, fy/z, -fy v/z]]
  f.J[0] = c.fx / zs; f.J[1] = 0.f; f.J[2] = -c.fx * (zs * f.u) / (zs * zs);
  f.J[3] = 0.f; f.J[4] = c.fy / zs; f.J[5] = -c.fy * (zs * f.v) / (zs * zs);
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      f.T[3 * i + j] = f.J[3 * i] * c.R[j] + f.J[3 * i + 1] * c.R[3 + j] + f.J[3 * i + 2] * c.R[6 + j];
  float TS[6];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      TS[3 * i + j] = f.T[3 * i] * f.Sig[j] + f.T[3 * i + 1] * f.Sig[3 + j] + f.T[3 * i + 2] * f.Sig[6 + j];
  f.cov[0] = TS[0] * f.T[0] + TS[1] * f.T[1] + TS[2] * f.T[2] + c.eps2d;
  f.cov[1] = TS[0] * f.T[3] + TS[1] * f.T[4] + TS[2] * f.T[5];
  f.cov[2] = TS[3] * f.T[3] + TS[4] * f.T[4] + TS[5] * f.T[5] + c.eps2d;
  f.det = f.cov[0] * f.cov[2] - f.cov[1] * f.cov[1];
  f.valid = f.valid && (f.det > 0.f) && std::isfinite(f.det);
}

}  // namespace proj

extern "C" {

// cam: [R(9), t(3), fx, fy, cx, cy, near, far, eps2d] floats.
void anigs_project_forward(int N, const float* cam, int W, int H, const float* means, const float* quats,
                           const float* scales, const float* opac, float* means2d, float* conics,
                           float* depths, int* rects, int* radii, unsigned char* valid, int nthreads) {
  const proj::Cam c = proj::unpack(cam, W, H);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(nthreads > 0 ? nthreads : 1)
#endif
  for (int g = 0; g < N; ++g) {
    proj::Fwd f;
    proj::forward_one(c, means + 3 * g, quats + 4 * g, scales + 3 * g, f);
    const float zs = (f.pc[2] > c.near && f.pc[2] < c.far) ? f.pc[2] : 1.f;
    const float mx = c.fx * f.pc[0] / zs + c.cx, my = c.fy * f.pc[1] / zs + c.cy;
    const float ds = f.valid ? f.det : 1.f;
    const float A = f.cov[2] / ds, B = -f.cov[1] / ds, C = f.cov[0] / ds;
    bool ok = f.valid && std::isfinite(mx) && std::isfinite(my) && std::isfinite(A) && std::isfinite(B) &&
              std::isfinite(C) && opac[g] >= 1.f / 255.f;
    means2d[2 * g] = mx; means2d[2 * g + 1] = my;
    conics[3 * g] = A; conics[3 * g + 1] = B; conics[3 * g + 2] = C;
    depths[g] = f.pc[2];
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
  }
}

// Gradients w.r.t. means [N,3], quats [N,4], scales [N,3] from grads of means2d, conics, depths.
void anigs_project_backward(int N, const float* cam, int W, int H, const float* means, const float* quats,
                            const float* scales, const unsigned char* valid, const float* g_means2d,
                            const float* g_conics, const float* g_depths, float* g_means, float* g_quats,
                            float* g_scales, int nthreads) {
  const proj::Cam c = proj::unpack(cam, W, H);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(nthreads > 0 ? nthreads : 1)
#endif
  for (int g = 0; g < N; ++g) {
    float* gm = g_means + 3 * g;
    float* gq = g_quats + 4 * g;
    float* gs = g_scales + 3 * g;
    gm[0] = gm[1] = gm[2] = 0.f;
    gq[0] = gq[1] = gq[2] = gq[3] = 0.f;
    gs[0] = gs[1] = gs[2] = 0.f;
    if (!valid[g]) continue;
    proj::Fwd f;
    const float* s = scales + 3 * g;
    proj::forward_one(c, means + 3 * g, quats + 4 * g, s, f);
    const float z = f.pc[2], x = f.pc[0], y = f.pc[1];
    const float a = f.cov[0], b = f.cov[1], cc = f.cov[2], det = f.det, det2 = det * det;
    const float gA = g_conics[3 * g], gB = g_conics[3 * g + 1], gC = g_conics[3 * g + 2];
    // conic (A,B,C) = (c, -b, a) / det  ->  grads w.r.t. the 2D covariance entries
    const float ga = gA * (-cc * cc / det2) + gB * (b * cc / det2) + gC * (-b * b / det2);
    const float gb = gA * (2.f * b * cc / det2) + gB * (-1.f / det - 2.f * b * b / det2) + gC * (2.f * a * b / det2);
    const float gc = gA * (-b * b / det2) + gB * (a * b / det2) + gC * (-a * a / det2);
    const float G[4] = {ga, 0.5f * gb, 0.5f * gb, gc};  // symmetric 2x2 gradient
    // cov2 = T Sig T^T: G_Sig = T^T G T, G_T = 2 G T Sig
    float GT[6], TS[6], GSig[9];
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 3; ++j) GT[3 * i + j] = G[2 * i] * f.T[j] + G[2 * i + 1] * f.T[3 + j];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) GSig[3 * i + j] = f.T[i] * GT[j] + f.T[3 + i] * GT[3 + j];
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 3; ++j)
        TS[3 * i + j] = f.T[3 * i] * f.Sig[j] + f.T[3 * i + 1] * f.Sig[3 + j] + f.T[3 * i + 2] * f.Sig[6 + j];
    float GTm[6];
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 3; ++j) GTm[3 * i + j] = 2.f * (G[2 * i] * TS[j] + G[2 * i + 1] * TS[3 + j]);
    // T = J Rv: G_J = G_T Rv^T
    float GJ[6];
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 3; ++j)
        GJ[3 * i + j] = GTm[3 * i] * c.R[3 * j] + GTm[3 * i + 1] * c.R[3 * j + 1] + GTm[3 * i + 2] * c.R[3 * j + 2];
    // J entries: J00 = fx/z, J02 = -fx u / z, J11 = fy/z, J12 = -fy v / z, u = clamp(x/z)
    float gx = 0.f, gy = 0.f, gz = 0.f;
    const float z2 = z * z, z3 = z2 * z;
    gz += GJ[0] * (-c.fx / z2) + GJ[4] * (-c.fy / z2);
    if (f.uclamped > 0.f) {
      gz += GJ[2] * (c.fx * f.u / z2);
    } else {
      gz += GJ[2] * (2.f * c.fx * x / z3);
      gx += GJ[2] * (-c.fx / z2);
    }
    if (f.vclamped > 0.f) {
      gz += GJ[5] * (c.fy * f.v / z2);
    } else {
      gz += GJ[5] * (2.f * c.fy * y / z3);
      gy += GJ[5] * (-c.fy / z2);
    }
    // means2d = (fx x/z + cx, fy y/z + cy); depth = z
    const float gm0 = g_means2d[2 * g], gm1 = g_means2d[2 * g + 1];
    gx += gm0 * c.fx / z;
    gy += gm1 * c.fy / z;
    gz += -gm0 * c.fx * x / z2 - gm1 * c.fy * y / z2 + g_depths[g];
    // pc = Rv mu + t
    for (int j = 0; j < 3; ++j) gm[j] = c.R[j] * gx + c.R[3 + j] * gy + c.R[6 + j] * gz;
    // Sig = M M^T (G_Sig symmetric): G_M = 2 G_Sig M;  M = Rq diag(s)
    float GM[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        GM[3 * i + j] = 2.f * (GSig[3 * i] * f.M[j] + GSig[3 * i + 1] * f.M[3 + j] + GSig[3 * i + 2] * f.M[6 + j]);
    float GR[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        gs[j] += GM[3 * i + j] * f.Rq[3 * i + j];
        GR[3 * i + j] = GM[3 * i + j] * s[j];
      }
    const float w = f.qn[0], qx = f.qn[1], qy = f.qn[2], qz = f.qn[3];
    float gqn[4];
    gqn[0] = 2.f * (-qz * GR[1] + qy * GR[2] + qz * GR[3] - qx * GR[5] - qy * GR[6] + qx * GR[7]);
    gqn[1] = 2.f * (qy * GR[1] + qz * GR[2] + qy * GR[3] - 2.f * qx * GR[4] - w * GR[5] + qz * GR[6] + w * GR[7] - 2.f * qx * GR[8]);
    gqn[2] = 2.f * (-2.f * qy * GR[0] + qx * GR[1] + w * GR[2] + qx * GR[3] + qz * GR[5] - w * GR[6] + qz * GR[7] - 2.f * qy * GR[8]);
    gqn[3] = 2.f * (-2.f * qz * GR[0] - w * GR[1] + qx * GR[2] + w * GR[3] - 2.f * qz * GR[4] + qy * GR[5] + qx * GR[6] + qy * GR[7]);
    // qn = q / max(|q|, eps)
    if (f.qnorm > 1e-12f) {
      const float dot = gqn[0] * w + gqn[1] * qx + gqn[2] * qy + gqn[3] * qz;
      for (int i = 0; i < 4; ++i) gq[i] = (gqn[i] - f.qn[i] * dot) / f.qnorm;
    } else {
      for (int i = 0; i < 4; ++i) gq[i] = gqn[i] / 1e-12f;
    }
  }
}

}  // extern "C"
