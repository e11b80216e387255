// Depth sort of the splats, off the main thread.
// Loaded as a classic script that only defines anigsSortWorker; viewer.js starts it as a Worker
// from a Blob of its source (works from file:// as well as over http).
// Order: ascending camera depth z (stable: ties keep input order, as the library's
// torch.argsort(stable=True)), splats with z <= near or z >= far dropped; sent back reversed
// (back to front) for "over" blending.
/* exported anigsSortWorker */
function anigsSortWorker(self) {
  "use strict";
  let N = 0, means = null, dyn = null, pos = null, K = 0, T = 1, maxOffset = null;
  let keys = null, idxA = null, idxB = null, keysB = null, counts = null;

  function basis(t) {
    const b = new Float64Array(K), s = Math.sqrt(2 / (K + 1));
    for (let k = 1; k <= K; k++) b[k - 1] = s * Math.cos(Math.PI / (2 * T) * (2 * t + 1) * k);
    return b;
  }

  function softLimit(v, L) { // L tanh(|v|/L) v/|v| (anigs.animate.deform.soft_limit)
    const n = Math.hypot(v[0], v[1], v[2]);
    if (!(L > 0) || n === 0) return v;
    const f = L * Math.tanh(n / L) / n;
    return [v[0] * f, v[1] * f, v[2] * f];
  }

  function sort(msg) {
    const r = msg.row, near = msg.near, far = msg.far;  // row: world->camera z row [r0,r1,r2,t]
    const z = new Float32Array(N);
    for (let i = 0; i < N; i++) {
      z[i] = r[0] * means[3 * i] + r[1] * means[3 * i + 1] + r[2] * means[3 * i + 2] + r[3];
    }
    if (dyn.length && K > 0) {
      const b = basis(msg.t);
      for (let j = 0; j < dyn.length; j++) {
        let d = [0, 0, 0];
        for (let a = 0; a < 3; a++) {
          let s = 0;
          const o = (j * 3 + a) * K;
          for (let k = 0; k < K; k++) s += pos[o + k] * b[k];
          d[a] = s;
        }
        if (maxOffset) d = softLimit(d, maxOffset[j]);
        const i = dyn[j];
        z[i] = r[0] * (means[3 * i] + d[0]) + r[1] * (means[3 * i + 1] + d[1]) + r[2] * (means[3 * i + 2] + d[2]) + r[3];
      }
    }
    // keep the visible depth range; positive float32 bit patterns sort like the numbers
    let m = 0;
    const zb = new Uint32Array(z.buffer);
    for (let i = 0; i < N; i++) {
      if (z[i] > near && z[i] < far) { keys[m] = zb[i]; idxA[m] = i; m++; }
    }
    // LSD radix sort, 3 passes of 11 bits: stable
    let kA = keys, kB = keysB, iA = idxA, iB = idxB;
    for (let shift = 0; shift < 32; shift += 11) {
      counts.fill(0);
      for (let i = 0; i < m; i++) counts[(kA[i] >>> shift) & 2047]++;
      let sum = 0;
      for (let c = 0; c < 2048; c++) { const v = counts[c]; counts[c] = sum; sum += v; }
      for (let i = 0; i < m; i++) {
        const dst = counts[(kA[i] >>> shift) & 2047]++;
        kB[dst] = kA[i]; iB[dst] = iA[i];
      }
      [kA, kB] = [kB, kA]; [iA, iB] = [iB, iA];
    }
    const out = new Uint32Array(m);
    for (let i = 0; i < m; i++) out[i] = iA[m - 1 - i];
    keys = kA; keysB = kB; idxA = iA; idxB = iB;
    return out;
  }

  self.onmessage = (e) => {
    const msg = e.data;
    if (msg.type === "init") {
      means = msg.means; dyn = msg.dyn; pos = msg.pos; K = msg.K; T = msg.T; maxOffset = msg.maxOffset;
      N = means.length / 3;
      keys = new Uint32Array(N); keysB = new Uint32Array(N);
      idxA = new Uint32Array(N); idxB = new Uint32Array(N); counts = new Uint32Array(2048);
    } else if (msg.type === "sort") {
      const t0 = performance.now();
      const order = sort(msg);
      self.postMessage({type: "sorted", id: msg.id, order, ms: performance.now() - t0}, [order.buffer]);
    }
  };
}
