// WebGL2 state of the splat renderer: data textures, programs, the float accumulation target.
"use strict";
var ANIGS = window.ANIGS || (window.ANIGS = {});

ANIGS.MAX_BASES = 64;

ANIGS.Renderer = class {
  // target: "auto" (RGBA32F if blendable, else RGBA16F, else 8-bit canvas) or one of those names
  constructor(canvas, target = "auto") {
    const gl = canvas.getContext("webgl2", {antialias: false, alpha: false, depth: false, stencil: false,
                                             premultipliedAlpha: false, preserveDrawingBuffer: true});
    if (!gl) throw new Error("WebGL2 is not available in this browser");
    this.gl = gl; this.canvas = canvas; this.count = 0;
    // float target: RGBA32F when it can be blended, else RGBA16F, else draw straight into the 8-bit canvas
    const cbf = gl.getExtension("EXT_color_buffer_float");
    const blend32 = cbf && gl.getExtension("EXT_float_blend");
    const best = blend32 ? "rgba32f" : cbf ? "rgba16f" : "rgba8", order = ["rgba8", "rgba16f", "rgba32f"];
    this.target = target !== "auto" && order.indexOf(target) >= 0 && order.indexOf(target) <= order.indexOf(best)
      ? target : best;
    this.project = this._program(ANIGS.PROJECT_VS, ANIGS.PROJECT_FS, ANIGS.PROJECT_VARYINGS);
    this.quad = this._program(ANIGS.QUAD_VS, ANIGS.SPLAT_FS);
    this.compose = this._program(ANIGS.COMPOSE_VS, ANIGS.COMPOSE_FS);
    this.texW = Math.min(4096, gl.getParameter(gl.MAX_TEXTURE_SIZE));
    // pass 1 reads the sorted indices and writes one 16-float record per splat (transform feedback);
    // the records are copied into recTex for pass 2
    this.indexBuf = gl.createBuffer();
    this.vaoProject = gl.createVertexArray();
    gl.bindVertexArray(this.vaoProject);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.indexBuf);
    const loc = gl.getAttribLocation(this.project.prog, "a_index");
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribIPointer(loc, 1, gl.UNSIGNED_INT, 0, 0);
    gl.bindVertexArray(null);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    this.splatBuf = gl.createBuffer(); this.splatCap = 0; this.recTex = null;
    this.tf = gl.createTransformFeedback();
    this.emptyVao = gl.createVertexArray();
  }

  _program(vsSrc, fsSrc, varyings) {
    const gl = this.gl, prog = gl.createProgram();
    for (const [type, src] of [[gl.VERTEX_SHADER, vsSrc], [gl.FRAGMENT_SHADER, fsSrc]]) {
      const sh = gl.createShader(type);
      gl.shaderSource(sh, src); gl.compileShader(sh);
      if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(sh));
      gl.attachShader(prog, sh);
    }
    if (varyings) gl.transformFeedbackVaryings(prog, varyings, gl.INTERLEAVED_ATTRIBS);
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error("link: " + gl.getProgramInfoLog(prog));
    const u = {}, n = gl.getProgramParameter(prog, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) {
      const name = gl.getActiveUniform(prog, i).name.replace(/\[0\]$/, "");
      u[name] = gl.getUniformLocation(prog, name);
    }
    return {prog, u};
  }

  _texture(unit, data, texels) {  // RGBA32F texture holding `texels` texels (row-major, width texW)
    const gl = this.gl, w = this.texW, h = Math.max(1, Math.ceil(texels / w));
    const full = new Float32Array(w * h * 4);
    full.set(data.subarray(0, Math.min(data.length, full.length)));
    const tex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + unit);
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, w, h, 0, gl.RGBA, gl.FLOAT, full);
    return tex;
  }

  // scene: ANIGS.parseCompact result. Packs the Gaussians into three float textures.
  upload(scene) {
    const h = scene.header, A = scene.arrays, N = h.num_gaussians, D = h.num_dynamic, K = h.num_bases;
    if (K > ANIGS.MAX_BASES) throw new Error("K = " + K + " DCT bases; the viewer supports up to " + ANIGS.MAX_BASES);
    const C = (h.sh_degree + 1) * (h.sh_degree + 1);
    const rowOf = new Float32Array(N).fill(-1);
    for (let j = 0; j < D; j++) rowOf[A.dynamic_index[j]] = j;
    const g = new Float32Array(N * 12);
    for (let i = 0; i < N; i++) {
      const o = 12 * i;
      g[o] = A.means[3 * i]; g[o + 1] = A.means[3 * i + 1]; g[o + 2] = A.means[3 * i + 2];
      g[o + 3] = 1 / (1 + Math.exp(-A.opacity_logits[i]));
      for (let c = 0; c < 4; c++) g[o + 4 + c] = A.quats[4 * i + c];
      for (let c = 0; c < 3; c++) g[o + 8 + c] = Math.exp(A.log_scales[3 * i + c]);
      g[o + 11] = rowOf[i];
    }
    const shTexels = C, sh = new Float32Array(N * C * 4);  // one texel (r,g,b,-) per SH coefficient
    for (let i = 0; i < N * C; i++) {
      sh[4 * i] = A.sh[3 * i]; sh[4 * i + 1] = A.sh[3 * i + 1]; sh[4 * i + 2] = A.sh[3 * i + 2];
    }
    const dynTexels = 2 * K + 1, dyn = new Float32Array(Math.max(1, D * dynTexels * 4));
    for (let j = 0; j < D; j++) {
      const base = 4 * dynTexels * j;
      for (let a = 0; a < 3; a++) {
        for (let k = 0; k < K; k++) {
          dyn[base + 4 * k + a] = A.pos_coeffs[(3 * j + a) * K + k];
          if (A.rot_coeffs) dyn[base + 4 * (K + k) + a] = A.rot_coeffs[(3 * j + a) * K + k];
        }
      }
      dyn[base + 8 * K] = A.max_offset ? A.max_offset[j] : -1;
      dyn[base + 8 * K + 1] = A.max_angle ? A.max_angle[j] : -1;
    }
    this.texG = this._texture(0, g, 3 * N);
    this.texSH = this._texture(1, sh, shTexels * N);
    this.texDyn = this._texture(2, dyn, Math.max(1, D * dynTexels));
    this.meta = {N, D, K, T: h.num_frames, shDegree: h.sh_degree, shTexels, dynTexels, rotation: !!h.rotation};
  }

  setOrder(order) {
    const gl = this.gl;
    gl.bindBuffer(gl.ARRAY_BUFFER, this.indexBuf);
    gl.bufferData(gl.ARRAY_BUFFER, order, gl.DYNAMIC_DRAW);
    this.count = order.length;
    if (this.count > this.splatCap) {  // whole texture rows: texW / 4 splats per row
      const perRow = this.texW / 4, rows = Math.ceil(this.count / perRow);
      this.splatCap = rows * perRow; this.recRows = rows;
      gl.bindBuffer(gl.ARRAY_BUFFER, this.splatBuf);
      gl.bufferData(gl.ARRAY_BUFFER, 64 * this.splatCap, gl.DYNAMIC_COPY);
      if (this.recTex) gl.deleteTexture(this.recTex);
      this.recTex = gl.createTexture();
      gl.activeTexture(gl.TEXTURE4);
      gl.bindTexture(gl.TEXTURE_2D, this.recTex);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, this.texW, rows);
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
  }

  _ensureTarget(W, H) {
    const gl = this.gl;
    if (this.target === "rgba8" || (this.fbo && this.fboW === W && this.fboH === H)) return;
    if (this.fbo) { gl.deleteFramebuffer(this.fbo); gl.deleteTexture(this.fboTex); }
    this.fboTex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE3);
    gl.bindTexture(gl.TEXTURE_2D, this.fboTex);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    const fmt = this.target === "rgba32f" ? gl.RGBA32F : gl.RGBA16F;
    gl.texStorage2D(gl.TEXTURE_2D, 1, fmt, W, H);
    this.fbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.fbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, this.fboTex, 0);
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) {
      this.target = "rgba8";  // not renderable after all: 8-bit fallback
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    this.fboW = W; this.fboH = H;
  }

  // s: {view: Float32Array(16) column-major world->camera, intr: [fx,fy,cx,cy], camPos: [3],
  //     basis: Float32Array(K), show: bool, bg: [3]}; draws into the canvas (its current size).
  draw(s) {
    const gl = this.gl, W = this.canvas.width, H = this.canvas.height, m = this.meta;
    this._ensureTarget(W, H);
    const p = this.project, u = p.u;
    gl.useProgram(p.prog);
    gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D, this.texG);
    gl.activeTexture(gl.TEXTURE1); gl.bindTexture(gl.TEXTURE_2D, this.texSH);
    gl.activeTexture(gl.TEXTURE2); gl.bindTexture(gl.TEXTURE_2D, this.texDyn);
    gl.uniform1i(u.u_g, 0); gl.uniform1i(u.u_sh, 1); gl.uniform1i(u.u_dyn, 2);
    gl.uniform1i(u.u_texW, this.texW); gl.uniform1i(u.u_shTexels, m.shTexels); gl.uniform1i(u.u_shDegree, m.shDegree);
    gl.uniform1i(u.u_K, m.K); gl.uniform1i(u.u_dynTexels, m.dynTexels); gl.uniform1i(u.u_rot, m.rotation ? 1 : 0);
    gl.uniform1i(u.u_show, s.show ? 1 : 0);
    gl.uniformMatrix4fv(u.u_view, false, s.view);
    gl.uniform4fv(u.u_intr, s.intr); gl.uniform2f(u.u_size, W, H); gl.uniform3fv(u.u_camPos, s.camPos);
    const basis = new Float32Array(ANIGS.MAX_BASES);
    basis.set(s.basis);
    gl.uniform1fv(u.u_basis, basis);
    gl.uniform1f(u.u_near, 0.01); gl.uniform1f(u.u_far, 1e10);
    if (this.count) {  // pass 1: per-splat motion, projection and colour into splatBuf
      gl.bindVertexArray(this.vaoProject);
      gl.enable(gl.RASTERIZER_DISCARD);
      gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, this.tf);
      gl.bindBufferRange(gl.TRANSFORM_FEEDBACK_BUFFER, 0, this.splatBuf, 0, 64 * this.count);
      gl.beginTransformFeedback(gl.POINTS);
      gl.drawArrays(gl.POINTS, 0, this.count);
      gl.endTransformFeedback();
      gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, null);
      gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, null);
      gl.disable(gl.RASTERIZER_DISCARD);
      gl.bindBuffer(gl.PIXEL_UNPACK_BUFFER, this.splatBuf);  // GPU-side copy records -> recTex
      gl.activeTexture(gl.TEXTURE4);
      gl.bindTexture(gl.TEXTURE_2D, this.recTex);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, this.texW, Math.ceil(this.count / (this.texW / 4)), gl.RGBA, gl.FLOAT, 0);
      gl.bindBuffer(gl.PIXEL_UNPACK_BUFFER, null);
    }
    // pass 2: blend the splats back to front
    const direct = this.target === "rgba8";
    gl.bindFramebuffer(gl.FRAMEBUFFER, direct ? null : this.fbo);
    gl.viewport(0, 0, W, H);
    if (direct) gl.clearColor(s.bg[0], s.bg[1], s.bg[2], 1); else gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.useProgram(this.quad.prog);
    gl.uniform2f(this.quad.u.u_size, W, H); gl.uniform1i(this.quad.u.u_texW, this.texW); gl.uniform1i(this.quad.u.u_rec, 4);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
    gl.bindVertexArray(this.emptyVao);
    if (this.count) gl.drawArrays(gl.TRIANGLES, 0, 6 * this.count);
    gl.bindVertexArray(null);
    gl.disable(gl.BLEND);
    if (!direct) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      gl.useProgram(this.compose.prog);
      gl.activeTexture(gl.TEXTURE3); gl.bindTexture(gl.TEXTURE_2D, this.fboTex);
      gl.uniform1i(this.compose.u.u_acc, 3);
      gl.uniform3fv(this.compose.u.u_bg, s.bg);
      gl.bindVertexArray(this.emptyVao);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      gl.bindVertexArray(null);
    }
  }

  // The canvas as RGBA bytes, top row first.
  readPixels() {
    const gl = this.gl, W = this.canvas.width, H = this.canvas.height;
    const buf = new Uint8Array(W * H * 4), out = new Uint8Array(W * H * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.readPixels(0, 0, W, H, gl.RGBA, gl.UNSIGNED_BYTE, buf);
    for (let y = 0; y < H; y++) out.set(buf.subarray((H - 1 - y) * W * 4, (H - y) * W * 4), y * W * 4);
    return out;
  }
};
