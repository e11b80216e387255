// The viewer application: loads the compact scene, runs the sort worker, playback, UI and the
// scripting API used by the tests (window.anigsViewer).
"use strict";
var ANIGS = window.ANIGS || (window.ANIGS = {});

// DCT basis of anigs.animate.deform.dct_basis: sqrt(2/(K+1)) cos(pi/(2T) (2t+1) k), k = 1..K
ANIGS.basis = function (t, T, K) {
  const b = new Float32Array(K), s = Math.sqrt(2 / (K + 1));
  for (let k = 1; k <= K; k++) b[k - 1] = s * Math.cos(Math.PI / (2 * T) * (2 * t + 1) * k);
  return b;
};

ANIGS.loadScript = (src) => new Promise((resolve, reject) => {
  const el = document.createElement("script");
  el.src = src; el.onload = resolve;
  el.onerror = () => reject(new Error("could not load " + src));
  document.head.appendChild(el);
});

ANIGS.loadSceneBuffer = async function (cfg) {
  if (location.protocol !== "file:" || !cfg.embedded) {
    try {
      const r = await fetch(cfg.data);
      if (r.ok) return await r.arrayBuffer();
    } catch (e) { /* file:// pages cannot fetch: use the embedded copy */ }
  }
  if (cfg.embedded) {
    await ANIGS.loadScript(cfg.embedded);
    return ANIGS.base64ToBuffer(window.ANIGS_SCENE_B64);
  }
  throw new Error("could not load " + cfg.data + " (from a file:// page run `anigs view --serve`)");
};

ANIGS.Viewer = class {
  constructor(cfg, ui) {
    this.cfg = cfg; this.ui = ui;
    const q = new URLSearchParams(location.search);
    this.scaleParam = q.get("scale");
    this.viewIndex = Math.min(Math.max(0, parseInt(q.get("view") || "0", 10)), Math.max(0, cfg.views.length - 1));
    this.t = parseFloat(q.get("t") || "0"); this.playing = q.get("paused") !== "1";
    this.speed = 1; this.loop = "pingpong"; this.dir = 1; this.show = q.get("moving") === "1";
    this.sortId = 0; this.inFlight = null; this.order = null; this.orderKey = null; this.waiters = [];
    this.stats = {fps: 0, sortMs: 0, frames: 0};
    this.ready = this._start().catch((e) => { this.ui.error(e); throw e; });
  }

  async _start() {
    const buf = await ANIGS.loadSceneBuffer(this.cfg);
    this.scene = ANIGS.parseCompact(buf);
    const h = this.scene.header;
    this.T = h.num_frames; this.K = h.num_bases;
    this.fps = this.cfg.fps || h.fps || 12;
    this.t = Math.min(Math.max(this.t, 0), this.T - 1);
    this.renderer = new ANIGS.Renderer(this.ui.canvas, new URLSearchParams(location.search).get("target") || "auto");
    this.renderer.upload(this.scene);
    const view = this.cfg.views[this.viewIndex];
    this.camera = new ANIGS.Camera(view ? view.camera : this._defaultCamera(), this.cfg.up);
    this._setOrbitDistance();
    this.controls = new ANIGS.Controls(this.ui.canvas, this.camera, () => { this.dirty = true; });
    this._startWorker();
    this._resize();
    window.addEventListener("resize", () => { this._resize(); this.dirty = true; });
    this.dirty = true; this.last = performance.now();
    requestAnimationFrame((now) => this._frame(now));
    this.ui.attach(this);
    return this;
  }

  _defaultCamera() {  // no views.json: look at the scene centre from outside
    const m = this.scene.arrays.means, n = m.length / 3, c = [0, 0, 0];
    for (let i = 0; i < n; i++) for (let a = 0; a < 3; a++) c[a] += m[3 * i + a] / n;
    const V = ANIGS.vec, up = V.norm(this.cfg.up || [0, 0, 1]);
    const eye = V.add(c, V.add(V.scale([1, 0, 0], 4), V.scale(up, 1.5)));
    const f = V.norm(V.sub(c, eye)), r = V.norm(V.cross(f, up)), d = V.cross(f, r);
    const rows = [r, d, f].map((x) => [x[0], x[1], x[2], -V.dot(x, eye)]).concat([[0, 0, 0, 1]]);
    return {K: [[256, 0, 320], [0, 256, 240], [0, 0, 1]], viewmat: rows, width: 640, height: 480};
  }

  _setOrbitDistance() {  // orbit about the moving region's centre, else 3 units ahead
    const c = this.cfg.roi_centroid, cam = this.camera;
    const d = c ? ANIGS.vec.dot(ANIGS.vec.sub(c, cam.pos), cam.fwd) : 0;
    cam.orbitDist = d > 0.05 ? d : 3;
  }

  _startWorker() {
    const src = "(" + anigsSortWorker.toString() + ")(self);";
    this.worker = new Worker(URL.createObjectURL(new Blob([src], {type: "text/javascript"})));
    const A = this.scene.arrays, h = this.scene.header;
    this.worker.postMessage({type: "init", means: A.means.slice(), dyn: A.dynamic_index.slice(),
                             pos: A.pos_coeffs.slice(), K: h.num_bases, T: h.num_frames,
                             maxOffset: A.max_offset ? A.max_offset.slice() : null});
    this.worker.onmessage = (e) => this._sorted(e.data);
  }

  _key() { return this.camera.fwd.join(",") + "|" + this.camera.pos.join(",") + "|" + this.t; }

  _requestSort() {
    if (this.inFlight) { this.wantSort = true; return; }
    const rows = this.camera.viewRows();
    this.inFlight = {id: ++this.sortId, key: this._key()};
    this.wantSort = false;
    this.worker.postMessage({type: "sort", id: this.sortId, row: rows[2], t: this.t, near: 0.01, far: 1e10});
  }

  _sorted(msg) {
    const key = this.inFlight.key;
    this.inFlight = null;
    this.renderer.setOrder(msg.order);
    this.orderKey = key; this.stats.sortMs = msg.ms; this.dirty = true;
    if (this.wantSort || key !== this._key()) this._requestSort();
    this._flushWaiters();
  }

  _flushWaiters() {
    if (!this.waiters.length || this.orderKey !== this._key()) return;
    this._draw();
    this.renderer.gl.finish();
    const w = this.waiters; this.waiters = [];
    w.forEach((resolve) => resolve());
  }

  _resize() {
    const cam = this.camera, dpr = window.devicePixelRatio || 1;
    const box = this.ui.viewport();
    let s = parseFloat(this.scaleParam);
    if (!(s > 0)) s = Math.max(0.1, Math.min(box.width / cam.width, box.height / cam.height) * dpr);
    const W = Math.max(1, Math.round(cam.width * s)), H = Math.max(1, Math.round(cam.height * s));
    this.ui.canvas.width = W; this.ui.canvas.height = H;
    this.ui.canvas.style.width = W / dpr + "px"; this.ui.canvas.style.height = H / dpr + "px";
  }

  _draw() {
    const c = this.ui.canvas, cam = this.camera;
    this.renderer.draw({view: cam.viewGL(), intr: cam.intrinsics(c.width, c.height), camPos: cam.pos,
                        basis: ANIGS.basis(this.t, this.T, this.K), show: this.show, bg: this.cfg.background});
    this.stats.frames++;
  }

  _frame(now) {
    const dt = Math.min(0.1, (now - this.last) / 1000);
    this.last = now;
    if (this.controls.update(dt)) this.dirty = true;
    if (this.playing && this.T > 1) {
      let t = this.t + this.dir * dt * this.fps * this.speed;
      if (t > this.T - 1) {
        if (this.loop === "pingpong") { t = 2 * (this.T - 1) - t; this.dir = -1; } else t -= this.T - 1;
      } else if (t < 0) { t = -t; this.dir = 1; }
      this.t = Math.min(Math.max(t, 0), this.T - 1);
      this.dirty = true;
    }
    if (this.dirty && this.orderKey !== this._key()) this._requestSort();
    if (this.dirty) { this._draw(); this.dirty = false; }
    if (now - (this.fpsT0 || 0) > 1000) {  // drawn frames per second over the last second
      this.stats.fps = this.fpsT0 ? 1000 * (this.stats.frames - this.fpsN0) / (now - this.fpsT0) : 0;
      this.fpsT0 = now; this.fpsN0 = this.stats.frames;
    }
    this.ui.update(this);
    requestAnimationFrame((n) => this._frame(n));
  }

  // ---- scripting API (tests, benchmarks) -------------------------------------------------
  setView(i) {
    this.viewIndex = i;
    this.camera.set(this.cfg.views[i].camera);
    this._setOrbitDistance(); this._resize(); this.dirty = true;
  }
  setCamera(cam) { this.camera.set(cam); this._resize(); this.dirty = true; }
  setScale(s) { this.scaleParam = s; this._resize(); this.dirty = true; }  // "fit" or a multiple of the view size
  setTime(t) { this.t = Math.min(Math.max(+t, 0), this.T - 1); this.dirty = true; }
  setPlaying(p) { this.playing = !!p; this.dirty = true; }
  setShowMoving(s) { this.show = !!s; this.dirty = true; }
  // resolves once the frame for the current camera and time is drawn with its own depth order
  renderExact() {
    return new Promise((resolve) => {
      this.waiters.push(resolve);
      if (this.orderKey !== this._key()) this._requestSort(); else this._flushWaiters();
    });
  }
  pixelsBase64() {
    const px = this.renderer.readPixels();
    let s = "";
    for (let i = 0; i < px.length; i += 0x8000) s += String.fromCharCode.apply(null, px.subarray(i, i + 0x8000));
    return btoa(s);
  }
  // n draws at times spread over the clip (fixed depth order), synchronised with a 1-pixel read
  benchmark(n) {
    const gl = this.renderer.gl, px = new Uint8Array(4), t0 = this.t;
    this._draw(); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const start = performance.now();
    for (let i = 0; i < n; i++) {
      this.t = (this.T - 1) * i / Math.max(1, n - 1);
      this._draw(); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    }
    const ms = (performance.now() - start) / n;
    this.t = t0; this.dirty = true;
    return {ms_per_frame: ms, fps: 1000 / ms, sort_ms: this.stats.sortMs, width: this.ui.canvas.width,
            height: this.ui.canvas.height, target: this.renderer.target, splats: this.renderer.count};
  }
  info() {
    const h = this.scene.header;
    return {num_gaussians: h.num_gaussians, num_dynamic: h.num_dynamic, num_frames: h.num_frames,
            num_bases: h.num_bases, sh_degree: h.sh_degree, target: this.renderer.target,
            width: this.ui.canvas.width, height: this.ui.canvas.height, t: this.t, playing: this.playing};
  }
};
