// GLSL of the splat renderer: the semantics of anigs.render.rasterize (EWA projection with the
// 1.3x-frustum Jacobian clamp, 0.3 px^2 dilation, opacity-aware 1/255 box, alpha clamp 0.99,
// alpha < 1/255 skipped, SH up to degree 3, background behind), with the DCT motion evaluated
// in the vertex shader (anigs.animate.deform.DCTDeformation). Splats are drawn back to front in
// the worker's depth order with premultiplied "over" blending into a float target.
"use strict";
var ANIGS = window.ANIGS || (window.ANIGS = {});

// Pass 1 (transform feedback, one invocation per splat in depth order): motion, projection, colour.
ANIGS.PROJECT_VS = `#version 300 es
precision highp float; precision highp int; precision highp sampler2D;
uniform sampler2D u_g, u_sh, u_dyn;
uniform int u_texW, u_shTexels, u_shDegree, u_K, u_dynTexels, u_rot, u_show;
uniform mat4 u_view; uniform vec4 u_intr; uniform vec2 u_size; uniform vec3 u_camPos;
uniform float u_basis[64]; uniform float u_near, u_far;
in uint a_index;
out vec4 v_rect, v_r1, v_r2, v_r3;  // one splat record: box; mean, opacity; conic; colour
vec4 fetch(sampler2D s, int L) { return texelFetch(s, ivec2(L % u_texW, L / u_texW), 0); }
vec3 softLimit(vec3 x, float L) {           // L tanh(|x|/L) x/|x|; L <= 0: no limit
  if (L <= 0.0) return x;
  L = max(L, 1e-6);
  float u2 = dot(x, x) / (L * L);
  if (u2 < 1e-6) return x * (1.0 - u2 / 3.0);
  float u = sqrt(u2);
  return x * (tanh(u) / u);
}
vec4 expQuat(vec3 w) {                      // so(3) -> unit quaternion (w,x,y,z)
  float th2 = dot(w, w);
  if (th2 < 1e-8) return vec4(1.0 - th2 / 8.0, w * (0.5 - th2 / 48.0));
  float th = sqrt(th2);
  return vec4(cos(th / 2.0), w * (sin(th / 2.0) / th));
}
vec4 qmul(vec4 a, vec4 b) {                 // Hamilton product, components (w,x,y,z) in .xyzw
  return vec4(a.x * b.x - a.y * b.y - a.z * b.z - a.w * b.w, a.x * b.y + a.y * b.x + a.z * b.w - a.w * b.z,
              a.x * b.z - a.y * b.w + a.z * b.x + a.w * b.y, a.x * b.w + a.y * b.z - a.z * b.y + a.w * b.x);
}
void cull() { v_rect = vec4(0.0); v_r1 = vec4(0.0); v_r2 = vec4(0.0); v_r3 = vec4(0.0); }
void main() {
  gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // nothing is rasterised in this pass
  int i = int(a_index);
  vec4 g0 = fetch(u_g, 3 * i), q = fetch(u_g, 3 * i + 1), g2 = fetch(u_g, 3 * i + 2);
  vec3 mu = g0.xyz, s = g2.xyz;
  float op = g0.w;
  int row = int(g2.w);
  if (row >= 0 && u_K > 0) {
    int base = row * u_dynTexels;
    vec3 dmu = vec3(0.0), w = vec3(0.0);
    for (int k = 0; k < u_K; k++) dmu += fetch(u_dyn, base + k).xyz * u_basis[k];
    vec4 lim = fetch(u_dyn, base + 2 * u_K);
    mu += softLimit(dmu, lim.x);
    if (u_rot == 1) {
      for (int k = 0; k < u_K; k++) w += fetch(u_dyn, base + u_K + k).xyz * u_basis[k];
      q = qmul(expQuat(softLimit(w, lim.y)), q);
    }
  }
  vec3 pc = (u_view * vec4(mu, 1.0)).xyz;
  if (!(pc.z > u_near && pc.z < u_far) || op < 1.0 / 255.0) { cull(); return; }
  float fx = u_intr.x, fy = u_intr.y, cx = u_intr.z, cy = u_intr.w, W = u_size.x, H = u_size.y, z = pc.z;
  float tanx = 0.5 * W / fx, tany = 0.5 * H / fy;
  float tx = z * clamp(pc.x / z, -(cx / fx + 0.3 * tanx), (W - cx) / fx + 0.3 * tanx);
  float ty = z * clamp(pc.y / z, -(cy / fy + 0.3 * tany), (H - cy) / fy + 0.3 * tany);
  mat3 Rv = mat3(u_view);
  vec3 T0 = vec3(fx / z, 0.0, -fx * tx / (z * z)) * Rv, T1 = vec3(0.0, fy / z, -fy * ty / (z * z)) * Rv;
  float qn = max(length(q), 1e-12);
  q /= qn;
  float qw = q.x, qx = q.y, qy = q.z, qz = q.w;
  mat3 Rq = mat3(1.0 - 2.0 * (qy * qy + qz * qz), 2.0 * (qx * qy + qw * qz), 2.0 * (qx * qz - qw * qy),
                 2.0 * (qx * qy - qw * qz), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz + qw * qx),
                 2.0 * (qx * qz + qw * qy), 2.0 * (qy * qz - qw * qx), 1.0 - 2.0 * (qx * qx + qy * qy));
  vec3 u0 = (T0 * Rq) * s, u1 = (T1 * Rq) * s;  // rows of J W R S
  float a = dot(u0, u0) + 0.3, b = dot(u0, u1), c = dot(u1, u1) + 0.3;
  float det = a * c - b * b;
  if (!(det > 0.0)) { cull(); return; }
  vec2 m = vec2(fx * pc.x / z + cx, fy * pc.y / z + cy);
  float level = 2.0 * log(max(op * 255.0, 1.0));
  float ex = sqrt(level * a), ey = sqrt(level * c);
  float x0 = clamp(ceil(m.x - ex - 0.5), 0.0, W), x1 = clamp(floor(m.x + ex - 0.5) + 1.0, 0.0, W);
  float y0 = clamp(ceil(m.y - ey - 0.5), 0.0, H), y1 = clamp(floor(m.y + ey - 0.5) + 1.0, 0.0, H);
  if (!(x1 > x0 && y1 > y0)) { cull(); return; }
  v_rect = vec4(x0, y0, x1, y1);  // pixels whose centre lies in the box (half-open)
  v_r1 = vec4(m, op, 0.0); v_r2 = vec4(c / det, -b / det, a / det, 0.0);
  // colour: SH of the direction camera -> (moved) Gaussian, max(SH + 0.5, 0) (anigs.geometry.sh)
  #define SH(n) fetch(u_sh, i * u_shTexels + (n)).rgb
  vec3 col = 0.28209479177387814 * SH(0);
  if (u_shDegree > 0) {
    vec3 d = normalize(mu - u_camPos);
    float x = d.x, y = d.y, zz = d.z;
    col += -0.4886025119029199 * y * SH(1) + 0.4886025119029199 * zz * SH(2) - 0.4886025119029199 * x * SH(3);
    if (u_shDegree > 1) {
      float xx = x * x, yy = y * y, z2 = zz * zz, xy = x * y, yz = y * zz, xz = x * zz;
      col += 1.0925484305920792 * xy * SH(4) - 1.0925484305920792 * yz * SH(5)
           + 0.31539156525252005 * (2.0 * z2 - xx - yy) * SH(6) - 1.0925484305920792 * xz * SH(7)
           + 0.5462742152960396 * (xx - yy) * SH(8);
      if (u_shDegree > 2) {
        col += -0.5900435899266435 * y * (3.0 * xx - yy) * SH(9) + 2.890611442640554 * xy * zz * SH(10)
             - 0.4570457994644658 * y * (4.0 * z2 - xx - yy) * SH(11)
             + 0.3731763325901154 * zz * (2.0 * z2 - 3.0 * xx - 3.0 * yy) * SH(12)
             - 0.4570457994644658 * x * (4.0 * z2 - xx - yy) * SH(13) + 1.445305721320277 * zz * (xx - yy) * SH(14)
             - 0.5900435899266435 * x * (xx - 3.0 * yy) * SH(15);
      }
    }
  }
  col = max(col + 0.5, 0.0);
  if (u_show == 1) {  // "show moving regions": moving splats magenta, still ones grey
    col = row >= 0 ? mix(col, vec3(1.0, 0.1, 0.6), 0.7) : vec3(0.25 + 0.5 * dot(col, vec3(0.299, 0.587, 0.114)));
  }
  v_r3 = vec4(col, 0.0);
}`;

ANIGS.PROJECT_FS = `#version 300 es
precision highp float; out vec4 o; void main() { o = vec4(0.0); }`;
ANIGS.PROJECT_VARYINGS = ["v_rect", "v_r1", "v_r2", "v_r3"];  // 16 floats per splat

// Pass 2: two triangles per splat covering its box (records copied into a texture, 4 texels per
// splat; plain triangles, not instancing, which software renderers run one instance at a time).
ANIGS.QUAD_VS = `#version 300 es
precision highp float; precision highp int; precision highp sampler2D;
uniform sampler2D u_rec; uniform int u_texW; uniform vec2 u_size;
flat out vec3 v_color; flat out vec2 v_mean; flat out vec3 v_conic; flat out float v_opacity;
vec4 fetch(int L) { return texelFetch(u_rec, ivec2(L % u_texW, L / u_texW), 0); }
void main() {
  int splat = gl_VertexID / 6, c = gl_VertexID % 6;
  vec4 rect = fetch(4 * splat);
  if (!(rect.z > rect.x)) { gl_Position = vec4(0.0, 0.0, 2.0, 1.0); return; }  // culled in pass 1
  vec4 r1 = fetch(4 * splat + 1);
  float px = (c == 1 || c == 2 || c == 4) ? rect.z : rect.x, py = (c == 2 || c == 4 || c == 5) ? rect.w : rect.y;
  gl_Position = vec4(2.0 * px / u_size.x - 1.0, 1.0 - 2.0 * py / u_size.y, 0.0, 1.0);
  v_mean = r1.xy; v_opacity = r1.z; v_conic = fetch(4 * splat + 2).xyz; v_color = fetch(4 * splat + 3).rgb;
}`;

ANIGS.SPLAT_FS = `#version 300 es
precision highp float;
flat in vec3 v_color; flat in vec2 v_mean; flat in vec3 v_conic; flat in float v_opacity;
uniform vec2 u_size;
out vec4 o;
void main() {
  vec2 d = vec2(gl_FragCoord.x, u_size.y - gl_FragCoord.y) - v_mean;  // pixel centre (y down) - mean
  float power = -0.5 * (v_conic.x * d.x * d.x + v_conic.z * d.y * d.y) - v_conic.y * d.x * d.y;
  if (power > 0.0) discard;
  float alpha = min(0.99, v_opacity * exp(power));
  if (alpha < 1.0 / 255.0) discard;
  o = vec4(v_color * alpha, alpha);
}`;

ANIGS.COMPOSE_VS = `#version 300 es
void main() { vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0); gl_Position = vec4(p, 0.0, 1.0); }`;

ANIGS.COMPOSE_FS = `#version 300 es
precision highp float;
uniform highp sampler2D u_acc; uniform vec3 u_bg;
out vec4 o;
void main() {
  vec4 a = texelFetch(u_acc, ivec2(gl_FragCoord.xy), 0);
  o = vec4(clamp(a.rgb + (1.0 - a.a) * u_bg, 0.0, 1.0), 1.0);
}`;
