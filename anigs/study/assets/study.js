// anigs 2AFC study page. The manifest (pairs, questions, seed) is inlined in index.html.
// Per participant: a seeded order of the pairs and a counterbalanced left/right assignment;
// every answer is saved to localStorage at once, posted to the study server when there is one,
// and can be downloaded as JSON. Schema of an answer: anigs/study/schema.py.
(function () {
  "use strict";
  const M = JSON.parse(document.getElementById("manifest").textContent);
  const N = M.trials.length;
  const PREFIX = "anigs-study:" + M.study_id + ":";
  const $ = (id) => document.getElementById(id);

  // ------------------------------------------------------------------ seeded randomness
  function hash32(str) {  // FNV-1a, then a murmur3 finaliser
    let h = 0x811c9dc5;
    for (let i = 0; i < str.length; i++) { h ^= str.charCodeAt(i); h = Math.imul(h, 0x01000193); }
    h ^= h >>> 16; h = Math.imul(h, 0x85ebca6b); h ^= h >>> 13; h = Math.imul(h, 0xc2b2ae35); h ^= h >>> 16;
    return h >>> 0;
  }
  function mulberry32(a) {
    return function () {
      a = (a + 0x6D2B79F5) | 0;
      let t = Math.imul(a ^ (a >>> 15), 1 | a);
      t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
      return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
    };
  }
  function shuffle(arr, rng) {
    for (let i = arr.length - 1; i > 0; i--) { const j = Math.floor(rng() * (i + 1)); [arr[i], arr[j]] = [arr[j], arr[i]]; }
    return arr;
  }
  function newParticipantId() {
    const b = new Uint8Array(6);
    crypto.getRandomValues(b);
    return "p-" + Array.from(b, (x) => x.toString(16).padStart(2, "0")).join("");
  }

  // ------------------------------------------------------------------ state (localStorage)
  function load(key) { try { return JSON.parse(localStorage.getItem(PREFIX + key)); } catch (e) { return null; } }
  function store(key, value) {
    try { localStorage.setItem(PREFIX + key, JSON.stringify(value)); return true; } catch (e) {
      showError("Could not save in this browser (" + e.message + "). Please download your answers regularly.");
      return false;
    }
  }
  function freshState(pid) {
    const seed = hash32(M.seed + ":" + pid);
    const rng = mulberry32(seed);
    const order = shuffle([...Array(N).keys()], rng);
    const half = Math.floor(N / 2);  // counterbalanced: ours on the left in half of the pairs
    const oursLeft = Array(half).fill(true).concat(Array(half).fill(false));
    if (N % 2) oursLeft.push(rng() < 0.5);
    shuffle(oursLeft, rng);
    return { participant: pid, seed: seed, order: order, oursLeft: oursLeft, pos: 0, draft: {},
             shown: -1, answers: [], unsent: [], rejected: [], started: false };
  }
  const urlPid = new URLSearchParams(location.search).get("participant");
  if (urlPid !== null && !/^[A-Za-z0-9_-]{1,64}$/.test(urlPid)) {
    document.body.innerHTML = "<p class='error'>Invalid participant code in the address: use letters, digits, '-' or '_'.</p>";
    throw new Error("invalid participant id");
  }
  const pid = urlPid || load("current") || newParticipantId();
  store("current", pid);
  let S = load("p:" + pid) || freshState(pid);
  if (S.order.length !== N) S = freshState(pid);
  const save = () => store("p:" + pid, S);
  save();

  // ------------------------------------------------------------------ sending and export
  let sending = false, retryMs = 1000;
  const postUrl = M.post_url && (location.protocol.startsWith("http") || /^https?:/.test(M.post_url)) ? M.post_url : null;
  function statusText() {
    const k = S.answers.length;
    let s = k + " answer" + (k === 1 ? "" : "s") + " saved in this browser";
    if (postUrl) s += "; sent to the server: " + (k - S.unsent.length - S.rejected.length) + " of " + k;
    if (S.rejected.length) s += "; " + S.rejected.length + " refused by the server (please download the file)";
    return s + ".";
  }
  function updateStatus() {
    $("save-status").textContent = statusText();
    if (!$("done").hidden) $("done-send").textContent = statusText();
  }
  async function flush() {
    if (!postUrl || sending || S.unsent.length === 0) { updateStatus(); return; }
    sending = true;
    let failed = false;
    const batch = S.answers.filter((a) => S.unsent.includes(answerId(a)));
    try {
      const r = await fetch(postUrl, { method: "POST", headers: { "Content-Type": "application/json" },
                                       body: JSON.stringify({ answers: batch }) });
      const ids = batch.map(answerId);
      if (r.ok) {
        S.unsent = S.unsent.filter((x) => !ids.includes(x)); retryMs = 1000;
      } else if (r.status >= 400 && r.status < 500) {  // refused: keep locally, do not retry forever
        const msg = await r.text();
        S.unsent = S.unsent.filter((x) => !ids.includes(x)); S.rejected.push(...ids);
        showError("The server refused answers: " + msg);
      } else { throw new Error("HTTP " + r.status); }
      save();
    } catch (e) {  // server unreachable or failing: retry with back-off, answers stay queued
      failed = true; setTimeout(flush, retryMs); retryMs = Math.min(retryMs * 2, 30000);
    } finally { sending = false; updateStatus(); }
    if (!failed && S.unsent.length) setTimeout(flush, 0);  // answers given while this post was under way
  }
  function exportData() {
    return { schema: "anigs-study-export/1", study_id: M.study_id, participant: pid, seed: S.seed,
             n_trials: N, complete: S.pos >= N, exported_at: new Date().toISOString(), answers: S.answers };
  }
  function download() {
    const blob = new Blob([JSON.stringify(exportData(), null, 1)], { type: "application/json" });
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = "anigs-study-" + M.study_id + "-" + pid + ".json";
    document.body.appendChild(a); a.click(); a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 10000);
  }
  const answerId = (a) => a.participant + "|" + a.pair + "|" + a.question;
  function showError(msg) { $("error").textContent = msg; $("error").hidden = false; }

  // ------------------------------------------------------------------ one trial
  const vids = [$("video-left"), $("video-right")];
  let t0 = null, plays = 0, ended = [false, false], reloaded = false;
  function current() {
    const t = M.trials[S.order[S.pos]];
    const left = S.oursLeft[S.pos] ? t.ours : t.other;
    return { trial: t, left: left, right: left === t.ours ? t.other : t.ours };
  }
  function unlocked() { return plays >= M.min_plays && t0 !== null; }
  function renderButtons() {
    const done = M.questions.every((q) => S.draft[q.id]);
    for (const q of M.questions) for (const side of ["left", "right"]) {
      const b = $("q-" + q.id + "-" + side);
      b.disabled = !unlocked();
      b.classList.toggle("selected", !!S.draft[q.id] && S.draft[q.id].side === side);
      b.setAttribute("aria-pressed", String(!!S.draft[q.id] && S.draft[q.id].side === side));
    }
    $("next").disabled = !(unlocked() && done);
    $("watch-note").textContent = t0 === null ? "Loading the videos\u2026"
      : unlocked() ? "Watched " + plays + " time" + (plays === 1 ? "" : "s") + ". Choose Left or Right for each question."
      : "Please watch both videos (" + plays + " of " + M.min_plays + " loops)\u2026";
  }
  function playBoth() { for (const v of vids) { v.currentTime = 0; const p = v.play(); if (p) p.catch(() => {}); } }
  function onEnded(i) {
    ended[i] = true;
    if (ended[0] && ended[1]) { ended = [false, false]; plays += 1; renderButtons(); playBoth(); }
  }
  function showTrial() {
    if (S.pos >= N) { showDone(); return; }
    const c = current();
    reloaded = S.shown === S.pos;  // this pair was on screen before a reload
    S.shown = S.pos; save();
    t0 = null; plays = 0; ended = [false, false];
    $("progress").textContent = "Pair " + (S.pos + 1) + " of " + N;
    $("progress-bar").style.width = (100 * S.pos / N) + "%";
    let ready = 0;
    vids.forEach((v, i) => {
      v.oncanplaythrough = null;
      v.onended = () => onEnded(i);
      v.onerror = () => showError("A video could not be played (" + v.getAttribute("src") + "). Please tell the experimenter.");
      v.oncanplaythrough = () => {
        v.oncanplaythrough = null;
        if (++ready === 2) { playBoth(); t0 = performance.now(); renderButtons(); }
      };
      v.src = c.trial.videos[i === 0 ? c.left : c.right];
      v.load();
    });
    renderButtons();
  }
  function choose(q, side) {
    if (!unlocked()) return;
    S.draft[q] = { side: side, time_ms: Math.round(performance.now() - t0), plays: plays, reloaded: reloaded };
    save(); renderButtons();
  }
  function next() {
    if ($("next").disabled) return;
    const c = current();
    for (const q of M.questions) {
      const d = S.draft[q.id];
      const a = { schema: "anigs-study-answer/1", study_id: M.study_id, participant: pid,
                  pair: c.trial.id, scene: c.trial.scene, view: c.trial.view, ours: c.trial.ours,
                  other: c.trial.other, question: q.id, left: c.left, side: d.side,
                  chosen: d.side === "left" ? c.left : c.right, time_ms: d.time_ms, trial: S.pos, n_trials: N,
                  answered_at: new Date().toISOString(), seed: S.seed, plays: d.plays, reloaded: d.reloaded };
      S.answers.push(a); S.unsent.push(answerId(a));
    }
    S.pos += 1; S.draft = {};
    save(); flush();
    showTrial();
  }
  function showDone() {
    vids.forEach((v) => { v.pause(); v.removeAttribute("src"); v.load(); });
    $("trial").hidden = true; $("intro").hidden = true; $("done").hidden = false;
    $("progress").textContent = "Done: " + N + " of " + N;
    $("progress-bar").style.width = "100%";
    $("n-done").textContent = N;
    updateStatus();
  }

  // ------------------------------------------------------------------ page set-up
  function buildQuestions() {
    const box = $("questions");
    M.questions.forEach((q, i) => {
      const row = document.createElement("div"); row.className = "question";
      const text = document.createElement("span"); text.className = "text";
      text.textContent = (i + 1) + ". " + q.text;
      row.appendChild(text);
      for (const side of ["left", "right"]) {
        const b = document.createElement("button");
        b.type = "button"; b.className = "choice"; b.id = "q-" + q.id + "-" + side;
        b.textContent = side === "left" ? "Left" : "Right";
        b.addEventListener("click", () => choose(q.id, side));
        row.appendChild(b);
      }
      box.appendChild(row);
    });
  }
  function start() {
    S.started = true; save();
    $("intro").hidden = true; $("trial").hidden = false; $("progress-wrap").hidden = false;
    showTrial();
  }
  function newParticipant() {
    if (S.unsent.length && !confirm("Some answers were not sent yet. Start over anyway?")) return;
    localStorage.removeItem(PREFIX + "current");
    location.search = "";
  }
  $("n-pairs").textContent = N;
  $("min-plays").textContent = M.min_plays === 1 ? "once" : M.min_plays + " times";
  for (const id of ["participant-intro", "participant-done", "participant-footer"]) $(id).textContent = pid;
  buildQuestions();
  $("start").textContent = S.pos > 0 ? "Continue (pair " + Math.min(S.pos + 1, N) + " of " + N + ")" : "Start";
  $("start").addEventListener("click", start);
  $("next").addEventListener("click", next);
  $("download").addEventListener("click", download);
  $("download-done").addEventListener("click", download);
  $("new-participant").addEventListener("click", newParticipant);
  if (S.started) start();  // a reload goes straight back to the pair on screen
  updateStatus(); flush();
  window.anigsStudy = { manifest: M, exportData: exportData, state: () => JSON.parse(JSON.stringify(S)),
                        unlocked: unlocked };
})();
