// Camera in the library's convention (OpenCV: x right, y down, z forward; viewmat world->camera)
// and the orbit / fly controls that move it.
"use strict";
var ANIGS = window.ANIGS || (window.ANIGS = {});

ANIGS.vec = {
  add: (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]],
  sub: (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]],
  scale: (a, s) => [a[0] * s, a[1] * s, a[2] * s],
  dot: (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2],
  cross: (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
  norm: (a) => { const n = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / n, a[1] / n, a[2] / n]; },
  // rotate v about unit axis k by angle (Rodrigues)
  rot: (v, k, ang) => {
    const c = Math.cos(ang), s = Math.sin(ang), V = ANIGS.vec, kv = V.cross(k, v), kd = V.dot(k, v) * (1 - c);
    return [v[0] * c + kv[0] * s + k[0] * kd, v[1] * c + kv[1] * s + k[1] * kd, v[2] * c + kv[2] * s + k[2] * kd];
  },
};

ANIGS.Camera = class {
  // cam: {K: 3x3, viewmat: 4x4 (row-major nested lists), width, height}; up: world up [3]
  constructor(cam, up) {
    this.up = ANIGS.vec.norm(up || [0, 0, 1]);
    this.set(cam);
    this.orbitDist = 3;
  }

  set(cam) {
    const M = cam.viewmat;
    this.right = [M[0][0], M[0][1], M[0][2]];
    this.down = [M[1][0], M[1][1], M[1][2]];
    this.fwd = [M[2][0], M[2][1], M[2][2]];
    const t = [M[0][3], M[1][3], M[2][3]];
    this.pos = [0, 1, 2].map((j) => -(this.right[j] * t[0] + this.down[j] * t[1] + this.fwd[j] * t[2]));
    this.K = cam.K; this.width = cam.width; this.height = cam.height;
  }

  // world->camera, column-major Float32Array(16) for GLSL, and row-major nested for export
  viewRows() {
    const V = ANIGS.vec, r = [this.right, this.down, this.fwd];
    return r.map((row) => [row[0], row[1], row[2], -V.dot(row, this.pos)]).concat([[0, 0, 0, 1]]);
  }
  viewGL() {
    const rows = this.viewRows(), out = new Float32Array(16);
    for (let r = 0; r < 4; r++) for (let c = 0; c < 4; c++) out[4 * c + r] = rows[r][c];
    return out;
  }
  // intrinsics at a render size W x H (scaled per axis, as anigs.cameras.Camera.scaled)
  intrinsics(W, H) {
    const sx = W / this.width, sy = H / this.height;
    return [this.K[0][0] * sx, this.K[1][1] * sy, this.K[0][2] * sx, this.K[1][2] * sy];
  }
  target() { return ANIGS.vec.add(this.pos, ANIGS.vec.scale(this.fwd, this.orbitDist)); }

  _rotate(axis, ang) {
    const V = ANIGS.vec;
    this.right = V.norm(V.rot(this.right, axis, ang));
    this.down = V.norm(V.rot(this.down, axis, ang));
    this.fwd = V.norm(V.cross(this.right, this.down));
    this.down = V.cross(this.fwd, this.right);
  }
  // yaw about world up, pitch about the camera's right axis; refuses to pitch over the pole
  look(yaw, pitch) {
    this._rotate(this.up, yaw);
    const f = ANIGS.vec.rot(this.fwd, this.right, pitch);
    if (Math.abs(ANIGS.vec.dot(f, this.up)) < 0.98) this._rotate(this.right, pitch);
  }
  orbit(yaw, pitch) {
    const V = ANIGS.vec, tgt = this.target();
    this.look(yaw, pitch);
    this.pos = V.sub(tgt, V.scale(this.fwd, this.orbitDist));
  }
  // move in camera axes (right, world up, forward)
  move(dr, du, df) {
    const V = ANIGS.vec;
    this.pos = V.add(this.pos, V.add(V.scale(this.right, dr), V.add(V.scale(this.up, du), V.scale(this.fwd, df))));
  }
  pan(dx, dy) {
    const V = ANIGS.vec;
    this.pos = V.add(this.pos, V.add(V.scale(this.right, dx), V.scale(this.down, dy)));
  }
  dolly(factor, orbitMode) {
    if (orbitMode) {
      const tgt = this.target();
      this.orbitDist = Math.max(1e-3, this.orbitDist * factor);
      this.pos = ANIGS.vec.sub(tgt, ANIGS.vec.scale(this.fwd, this.orbitDist));
    } else {
      this.move(0, 0, (1 - factor) * this.orbitDist);
    }
  }
};

// Mouse and keyboard: drag = orbit (orbit mode) or look around (fly mode); right/shift drag = pan;
// wheel = dolly; W/A/S/D move, Q/E down/up, arrows look, Shift faster.
ANIGS.Controls = class {
  constructor(el, camera, onChange) {
    this.cam = camera; this.onChange = onChange; this.mode = "orbit"; this.keys = new Set();
    let last = null, button = 0;
    el.addEventListener("contextmenu", (e) => e.preventDefault());
    el.addEventListener("pointerdown", (e) => {
      last = [e.clientX, e.clientY]; button = e.button === 2 || e.shiftKey ? 2 : 0;
      el.setPointerCapture(e.pointerId);
    });
    el.addEventListener("pointerup", () => { last = null; });
    el.addEventListener("pointermove", (e) => {
      if (!last) return;
      const dx = e.clientX - last[0], dy = e.clientY - last[1];
      last = [e.clientX, e.clientY];
      const c = this.cam;
      if (button === 2) c.pan(-dx * c.orbitDist * 0.002, -dy * c.orbitDist * 0.002);
      else if (this.mode === "orbit") c.orbit(-dx * 0.005, -dy * 0.005);
      else c.look(-dx * 0.003, -dy * 0.003);
      this.onChange();
    });
    el.addEventListener("wheel", (e) => {
      e.preventDefault();
      this.cam.dolly(Math.exp(e.deltaY * 0.001), this.mode === "orbit");
      this.onChange();
    }, {passive: false});
    window.addEventListener("keydown", (e) => {
      if (e.target && (e.target.tagName === "INPUT" || e.target.tagName === "SELECT")) return;
      this.keys.add(e.code);
    });
    window.addEventListener("keyup", (e) => this.keys.delete(e.code));
    window.addEventListener("blur", () => this.keys.clear());
  }

  // advance by dt seconds of held keys; returns true when the camera moved
  update(dt) {
    const k = this.keys, c = this.cam;
    if (!k.size) return false;
    const sp = c.orbitDist * 0.6 * dt * (k.has("ShiftLeft") || k.has("ShiftRight") ? 4 : 1);
    const ax = (a, b) => (k.has(a) ? 1 : 0) - (k.has(b) ? 1 : 0);
    const f = ax("KeyW", "KeyS"), r = ax("KeyD", "KeyA"), u = ax("KeyE", "KeyQ");
    const yaw = ax("ArrowLeft", "ArrowRight"), pitch = ax("ArrowUp", "ArrowDown");
    if (!(f || r || u || yaw || pitch)) return false;
    c.move(r * sp, u * sp, f * sp);
    if (yaw || pitch) c.look(yaw * 1.2 * dt, pitch * 1.2 * dt);
    return true;
  }
};
