// The page's controls: play/pause, time slider, speed, loop, "moving regions", views, mode, help.
"use strict";
var ANIGS = window.ANIGS || (window.ANIGS = {});

ANIGS.UI = class {
  constructor(root) {
    this.root = root;
    this.canvas = root.querySelector("#canvas");
    this.$ = (id) => root.querySelector("#" + id);
  }

  viewport() { const r = this.$("stage").getBoundingClientRect(); return {width: r.width, height: r.height}; }

  error(e) {
    const el = this.$("error");
    el.textContent = "Cannot show the scene: " + (e && e.message ? e.message : e);
    el.hidden = false;
    this.$("loading").hidden = true;
  }

  attach(v) {
    const $ = this.$;
    $("loading").hidden = true;
    const slider = $("time");
    slider.max = String(v.T - 1);
    slider.addEventListener("input", () => { v.setPlaying(false); v.setTime(parseFloat(slider.value)); });
    $("play").addEventListener("click", () => v.setPlaying(!v.playing));
    $("speed").addEventListener("change", (e) => { v.speed = parseFloat(e.target.value); });
    $("loop").addEventListener("change", (e) => { v.loop = e.target.value; v.dir = 1; });
    $("moving").checked = v.show;
    $("moving").addEventListener("change", (e) => v.setShowMoving(e.target.checked));
    const views = $("views");
    v.cfg.views.forEach((view, i) => {
      const o = document.createElement("option");
      o.value = String(i); o.textContent = view.id || "view " + i;
      views.appendChild(o);
    });
    views.value = String(v.viewIndex);
    views.addEventListener("change", (e) => v.setView(parseInt(e.target.value, 10)));
    $("mode").addEventListener("change", (e) => { v.controls.mode = e.target.value; });
    $("reset").addEventListener("click", () => v.setView(v.viewIndex));
    const res = $("res");
    if (v.scaleParam && [...res.options].some((o) => o.value === v.scaleParam)) res.value = v.scaleParam;
    res.addEventListener("change", () => v.setScale(res.value));
    $("helpbtn").addEventListener("click", () => { $("help").hidden = !$("help").hidden; });
    window.addEventListener("keydown", (e) => {
      if (e.target && (e.target.tagName === "INPUT" || e.target.tagName === "SELECT")) return;
      const step = (d) => { v.setPlaying(false); v.setTime(Math.round(v.t) + d); };
      const keys = {
        Space: () => v.setPlaying(!v.playing), KeyM: () => { $("moving").checked = !v.show; v.setShowMoving(!v.show); },
        KeyR: () => v.setView(v.viewIndex), Comma: () => step(-1), Period: () => step(1),
        KeyF: () => { v.controls.mode = v.controls.mode === "orbit" ? "fly" : "orbit"; $("mode").value = v.controls.mode; },
        BracketLeft: () => this._speed(v, -1), BracketRight: () => this._speed(v, 1),
        KeyH: () => { $("help").hidden = !$("help").hidden; },
      };
      const digit = /^Digit([1-9])$/.exec(e.code);
      if (digit && +digit[1] <= v.cfg.views.length) { v.setView(+digit[1] - 1); views.value = String(v.viewIndex); }
      else if (keys[e.code]) keys[e.code]();
      else return;
      e.preventDefault();
    });
    const h = v.scene.header;
    $("scene").textContent = `${h.num_gaussians.toLocaleString()} Gaussians, ${h.num_dynamic.toLocaleString()} moving` +
      ` · T=${h.num_frames}, K=${h.num_bases} · SH ${h.sh_degree}`;
  }

  _speed(v, d) {
    const sel = this.$("speed"), i = Math.min(sel.options.length - 1, Math.max(0, sel.selectedIndex + d));
    sel.selectedIndex = i; v.speed = parseFloat(sel.value);
  }

  update(v) {
    const $ = this.$;
    if (document.activeElement !== $("time")) $("time").value = String(v.t);
    $("tlabel").textContent = `t = ${v.t.toFixed(2)} / ${v.T - 1}`;
    $("play").textContent = v.playing ? "❚❚" : "▶";
    $("play").title = v.playing ? "pause (space)" : "play (space)";
    const rate = v.stats.fps > 0 ? `${v.stats.fps.toFixed(1)} fps` : "idle";
    $("stats").textContent = `${rate} · sort ${v.stats.sortMs.toFixed(1)} ms · ` +
      `${v.ui.canvas.width}x${v.ui.canvas.height} · ${v.renderer.target}`;
  }
};

window.addEventListener("DOMContentLoaded", () => {
  const ui = new ANIGS.UI(document.body);
  window.anigsViewer = new ANIGS.Viewer(window.ANIGS_CONFIG || {views: []}, ui);
});
