// Author: a timeline of keyframe tracks (AU poses), gaze, expression clips and blinks; play, scrub and
// loop on the twin or the head; record slider moves into keyframes; load and save the TOML script that
// `servoface play` reads.

import { h, clear, fmt, throttle } from "./dom.js";
import { GazePad } from "./gazepad.js";
import { SliderBoard } from "./sliders.js";
import { TimelineView } from "./timeline_view.js";
import { EASINGS, duration, emptyDocument, fromDocument, gazePad, keyTrack, padToPoint, sortKeys, toDocument } from "./timeline.js";

let ctx, model, view, board, inspector, preview, statusLine, fields = {};
let selected = null; // {row, id}
let time = 0, playing = null, recording = null;
let previewBusy = false, previewWanted = null, previewUrl = null, previewNote = null;

export function mount(el, c) {
  ctx = c;
  model = fromDocument(emptyDocument(ctx.head.face_type));
  keyTrack(model, "face");
  view = new TimelineView({
    onSelect: (row, id) => select({ row, id }),
    onMove: (row, id, t) => moveItem(row, id, t),
    onAdd: (row, t) => addAt(row, t),
    onScrub: (t) => seek(t),
  });
  board = new SliderBoard(ctx.head, { onChange: poseChanged, onRelease: poseReleased });
  board.el.classList.add("compact");
  inspector = h("div.inspector");
  preview = h("img.twin-img#author-twin", { alt: "the script on the twin at the playhead" });
  statusLine = h("div.status-line#author-status", {}, "New timeline: double-click a track to add a key, or use the buttons.");
  fields.time = h("span.time#author-time", {}, "0.00 s");
  previewNote = h("div.muted.preview-note#author-preview-note");
  const twinCard = h("div.card.author-twin", {}, h("div.card-head", {}, h("h3", {}, "Twin at the playhead"), h("span.grow"), fields.time), h("figure.twin-fig", {}, preview), previewNote);
  const timelineCard = h("div.card.timeline-card", {}, addBar(), view.el, statusLine);
  el.append(h("div.author", {}, toolbar(), h("div.author-grid", {}, twinCard, h("div.inspector-col", {}, inspector), timelineCard)));
  ctx.sliderListeners?.add((values) => recording && !recording.stream && recordPose(values));
  window.addEventListener("keydown", (ev) => {
    if (el.hidden || /^(INPUT|SELECT|TEXTAREA)$/.test(document.activeElement?.tagName || "")) return;
    if (ev.key === " ") {
      ev.preventDefault();
      playing ? stop() : play();
    } else if ((ev.key === "Delete" || ev.key === "Backspace") && selected) {
      ev.preventDefault();
      removeSelected();
    }
  });
  refresh();
  loadList();
}

// ---- toolbar -------------------------------------------------------------------------------------
function toolbar() {
  fields.list = h("select#author-list", {}, h("option", { value: "" }, "open a script…"));
  fields.list.addEventListener("change", () => fields.list.value && load(fields.list.value));
  fields.name = h("input#author-name", { type: "text", value: "studio_timeline.toml", size: "22", title: "file name in the studio's scripts folder" });
  fields.title = h("input#author-title", { type: "text", placeholder: "title", size: "20" });
  fields.title.addEventListener("change", () => (model.title = fields.title.value));
  fields.end = h("input.num#author-end", { type: "number", min: "0.1", step: "0.1", title: "end of the script (s)" });
  fields.end.addEventListener("change", () => {
    model.end_s = Math.max(0.1, Number(fields.end.value) || 1);
    refresh();
  });
  fields.target = h("select#author-on", {}, h("option", { value: "twin" }, "on the twin"), h("option", { value: "head" }, "on the head"));
  fields.loop = h("input#author-loop", { type: "checkbox" });
  fields.play = h("button.btn.primary#author-play", { onclick: () => (playing ? stop() : play()) }, "▶ Play");
  fields.rec = h("button.btn#author-record", { onclick: () => (recording ? stopRecording() : startRecording()), title: "record the Live page's (or the panel's) slider moves, or a live tracker stream, into keys on the face track" }, "● Record");
  fields.recSource = h(
    "select#author-rec-source",
    { title: "what Record records: slider moves, or a tracker's AU frames (the messages `servoface stream` takes) on a loopback port" },
    h("option", { value: "sliders" }, "sliders"),
    h("option", { value: "udp" }, "UDP stream"),
    h("option", { value: "tcp" }, "TCP stream"),
  );
  fields.recPort = h("input.num#author-rec-port", { type: "number", min: "0", max: "65535", value: "9100", title: "the stream's port on 127.0.0.1 (0: a free one)" });
  fields.recSource.addEventListener("change", () => (fields.recPort.hidden = fields.recSource.value === "sliders"));
  fields.recPort.hidden = true;
  fields.blink = h("input#author-blink", { type: "checkbox" });
  fields.blink.addEventListener("change", () => {
    model.blink = fields.blink.checked;
    refresh();
  });
  return h(
    "div.card.toolbar",
    {},
    fields.list,
    h("button.btn.ghost", { onclick: newTimeline }, "New"),
    fields.name,
    h("button.btn#author-save", { onclick: save }, "Save"),
    h("span.sep"),
    fields.title,
    h("label", {}, "end ", fields.end, " s"),
    h("span.sep"),
    fields.play,
    fields.target,
    h("label.toggle", {}, fields.loop, h("span", {}, "loop")),
    fields.rec,
    fields.recSource,
    fields.recPort,
    h("span.sep"),
    h("label.toggle", {}, fields.blink, h("span", {}, "blinks")),
  );
}

function addBar() {
  const lib = h("select#author-lib", {}, ctx.head.expressions.map((n) => h("option", { value: n }, n)));
  return h(
    "div.add-bar",
    {},
    h("button.chip#author-add-key", { onclick: () => addAt("keys:face", time) }, "+ face key at playhead"),
    h("button.chip#author-add-gaze", { onclick: () => addAt("gaze", time) }, "+ gaze key"),
    lib,
    h("button.chip#author-add-clip", { onclick: () => addClip(lib.value, time) }, "+ expression clip"),
    h("button.chip#author-add-say", { onclick: () => addSay(time) }, "+ speech at playhead"),
    h("span.grow"),
    h("span.muted", {}, "Space: play / stop · Delete: remove the selected key"),
    h("button.chip", { onclick: () => zoom(1.25), title: "zoom in" }, "zoom +"),
    h("button.chip", { onclick: () => zoom(0.8), title: "zoom out" }, "zoom −"),
  );
}

function zoom(f) {
  view.pxPerS = Math.max(40, Math.min(600, view.pxPerS * f));
  refresh();
}

// ---- rows ----------------------------------------------------------------------------------------
function rows() {
  const out = [];
  for (const t of model.tracks) {
    out.push({ id: `keys:${t.track}`, label: t.track, hint: "AU keys", kind: "keys", items: t.keys.map((k, i) => ({ id: i, t_s: k.t_s, text: poseText(k.pose) })) });
  }
  out.push({ id: "gaze", label: "gaze", hint: "look at", kind: "keys", items: model.gaze.map((g, i) => ({ id: i, t_s: g.at_s || 0, text: g.ahead ? "ahead" : (g.look_at_mm || []).join(", ") + " mm" })) });
  const clipTracks = [...new Set(model.clips.map((c) => c.track)), "gesture", "speech"].filter((v, i, a) => a.indexOf(v) === i);
  for (const track of clipTracks) {
    const items = model.clips.map((c, i) => ({ c, i })).filter(({ c }) => c.track === track).map(({ c, i }) => ({ id: i, t_s: c.entry.at_s || 0, end_s: (c.entry.at_s || 0) + clipLength(c), text: clipText(c.entry) }));
    if (track === "speech" || items.length || track === "gesture") out.push({ id: `clips:${track}`, label: track, hint: track === "speech" ? "speech" : "clips", kind: "clips", items });
  }
  out.push({ id: "blink", label: "blink", hint: "alive", kind: "toggle", items: [], text: model.blink ? "spontaneous blinks on" : "off" });
  return out;
}

function poseText(pose) {
  const parts = Object.entries(pose || {}).filter(([, v]) => Math.abs(v) > 0.004).map(([k, v]) => `${k} ${fmt(v)}`);
  return parts.length ? parts.join(", ") : "neutral";
}

/** Drawn length: a speech cue's from its words (espeak-ng speaks ~14 characters a second), else 1.5 s. */
function clipLength(c) {
  if (c.entry.say != null) return Math.max(0.4, String(c.entry.say).length / 14);
  return c.length_s || 1.5;
}

function clipText(entry) {
  if (entry.say != null) return `“${entry.say}”`;
  return entry.library || entry.expression || entry.recipe || (entry.sequence || []).join(" → ") || "clip";
}

function refresh() {
  fields.title.value = model.title || "";
  fields.end.value = model.end_s != null ? String(model.end_s) : "";
  fields.end.placeholder = duration(model).toFixed(1);
  fields.blink.checked = !!model.blink;
  view.selected = selected;
  view.render(rows(), model.end_s || duration(model));
  renderInspector();
}

// ---- editing -------------------------------------------------------------------------------------
function itemOf(sel) {
  if (!sel) return null;
  if (sel.row.startsWith("keys:")) {
    const t = model.tracks.find((x) => `keys:${x.track}` === sel.row);
    return t && t.keys[sel.id] ? { kind: "key", track: t, key: t.keys[sel.id] } : null;
  }
  if (sel.row === "gaze") return model.gaze[sel.id] ? { kind: "gaze", gaze: model.gaze[sel.id] } : null;
  if (sel.row.startsWith("clips:")) return model.clips[sel.id] ? { kind: "clip", clip: model.clips[sel.id] } : null;
  return null;
}

function select(sel) {
  selected = sel;
  const item = itemOf(sel);
  if (item && item.kind === "key") seek(item.key.t_s);
  else if (item && item.kind === "gaze") seek(item.gaze.at_s || 0);
  else if (item && item.kind === "clip") seek(item.clip.entry.at_s || 0);
  refresh();
}

function moveItem(row, id, t) {
  const item = itemOf({ row, id });
  if (!item) return;
  if (item.kind === "key") {
    const key = item.key;
    key.t_s = t;
    sortKeys(item.track);
    selected = { row, id: item.track.keys.indexOf(key) };
  } else if (item.kind === "gaze") {
    item.gaze.at_s = t;
  } else item.clip.entry.at_s = t;
  refresh();
  seek(t);
}

function addAt(row, t) {
  t = Math.round(t * 100) / 100;
  if (row.startsWith("keys:")) {
    const track = keyTrack(model, row.slice(5));
    const existing = track.keys.findIndex((k) => Math.abs(k.t_s - t) < 0.005);
    if (existing >= 0) {
      selected = { row, id: existing };
    } else {
      const before = [...track.keys].reverse().find((k) => k.t_s <= t);
      const key = { t_s: t, pose: { ...(before ? before.pose : {}) }, easing: "min_jerk" };
      track.keys.push(key);
      sortKeys(track);
      selected = { row, id: track.keys.indexOf(key) };
    }
  } else if (row === "gaze") {
    model.gaze.push({ at_s: t, look_at_mm: padToPoint([0, 0]) });
    model.gaze.sort((a, b) => a.at_s - b.at_s);
    selected = { row, id: model.gaze.findIndex((g) => g.at_s === t) };
  } else if (row === "clips:speech") {
    addSay(t);
    return;
  } else if (row.startsWith("clips:")) {
    addClip(ctx.head.expressions[0], t, row.slice(6));
    return;
  }
  refresh();
  schedulePreview();
}

function addClip(name, t, track = "gesture") {
  model.clips.push({ index: 1e6 + model.clips.length, track, entry: { at_s: Math.round(t * 100) / 100, track, library: name } });
  selected = { row: `clips:${track}`, id: model.clips.length - 1 };
  refresh();
  schedulePreview();
}

/** A speech cue (`[[play]] say = "..."`): the server synthesises it (espeak-ng) into the mouth's visemes. */
function addSay(t, text = "Hello.") {
  model.clips.push({ index: 1e6 + model.clips.length, track: "speech", entry: { at_s: Math.round(t * 100) / 100, track: "speech", say: text } });
  selected = { row: "clips:speech", id: model.clips.length - 1 };
  refresh();
  schedulePreview();
  document.querySelector("#say-text")?.focus();
}

function removeSelected() {
  const item = itemOf(selected);
  if (!item) return;
  if (item.kind === "key") item.track.keys.splice(selected.id, 1);
  else if (item.kind === "gaze") model.gaze.splice(selected.id, 1);
  else model.clips.splice(selected.id, 1);
  selected = null;
  refresh();
  schedulePreview();
}

function poseChanged(aus) {
  const item = itemOf(selected);
  if (recording && !recording.stream) {
    recordPose({ ...board.values });
    return;
  }
  if (!item || item.kind !== "key") return;
  Object.assign(item.key.pose, aus);
  delete item.key.poseName;
  if (inspector.summary) inspector.summary.textContent = poseText(item.key.pose);
  view.render(rows(), model.end_s || duration(model));
  schedulePreview();
}

function poseReleased(names) {
  const item = itemOf(selected);
  if (!item || item.kind !== "key") return;
  for (const n of names) delete item.key.pose[n];
  refresh();
  schedulePreview();
}

function renderInspector() {
  const item = itemOf(selected);
  if (!item) {
    clear(inspector, h("div.card", {}, h("h3", {}, "Keyframe"), h("p.muted", {}, "Select a key on the timeline, or add one. Each face key is a complete AU pose, reached at its time with its easing."), recording && !recording.stream ? recordCard() : null));
    return;
  }
  const time = h("input.num#key-time", { type: "number", min: "0", step: "0.05", value: String(item.kind === "key" ? item.key.t_s : item.kind === "gaze" ? item.gaze.at_s : item.clip.entry.at_s) });
  time.addEventListener("change", () => moveItem(selected.row, selected.id, Math.max(0, Number(time.value) || 0)));
  const del = h("button.btn.danger-ghost#key-delete", { onclick: removeSelected }, "Delete");
  if (item.kind === "key") {
    const easing = h("select#key-easing", {}, EASINGS.map((e) => h("option", { value: e, selected: (item.key.easing || "linear") === e }, e.replace(/_/g, " "))));
    easing.addEventListener("change", () => {
      item.key.easing = easing.value;
      schedulePreview();
    });
    const takeLive = h("button.btn.ghost", {
      title: "copy the pose of the Live page's sliders into this key",
      onclick: () => {
        item.key.pose = { ...(ctx.sliders?.values || {}) };
        refresh();
        schedulePreview();
      },
    }, "Take Live pose");
    // The pose editor: this key's AUs (or every AU); a sided AU in a key splits its region.
    for (const name of Object.keys(item.key.pose)) {
      const region = (ctx.head.aus.find((a) => a.name === name.replace(/[LR]$/, "")) || {}).region;
      if (/[LR]$/.test(name) && region && !board.split.has(region)) {
        board.split.add(region);
        board.render();
      }
    }
    board.setValues(item.key.pose);
    const only = h("input#key-only", { type: "checkbox", checked: Object.keys(item.key.pose).length > 0 });
    const filter = () => board.showOnly(only.checked ? Object.keys(item.key.pose) : null);
    only.addEventListener("change", filter);
    const names = ctx.head.aus.flatMap((a) => (a.sided ? [a.name, `${a.name}L`, `${a.name}R`] : [a.name]));
    const add = h("select#key-add-au", {}, h("option", { value: "" }, "add an AU…"), names.map((n) => h("option", { value: n }, `${n} ${(ctx.head.aus.find((a) => a.name === n.replace(/[LR]$/, "")) || {}).label || ""}`)));
    add.addEventListener("change", () => {
      const name = add.value;
      if (!name) return;
      if (!(name in item.key.pose)) item.key.pose[name] = 0;
      add.value = "";
      renderInspector();
    });
    const summary = h("p.pose-summary", {}, poseText(item.key.pose));
    clear(
      inspector,
      h(
        "div.card",
        {},
        h("div.card-head", {}, h("h3", {}, `Key on ${item.track.track}`), h("span.muted", {}, `${item.key.t_s.toFixed(2)} s`), h("span.grow"), del),
        h("div.form-row", {}, h("label", {}, "time ", time, " s"), h("label", {}, "easing in ", easing), takeLive),
        summary,
        h("div.form-row", {}, h("label.toggle", {}, only, h("span", {}, "only this key's AUs")), add),
      ),
      board.el,
    );
    filter();
    inspector.summary = summary;
  } else if (item.kind === "gaze") {
    const pad = new GazePad((p) => {
      if (p) {
        item.gaze.look_at_mm = padToPoint(p);
        delete item.gaze.ahead;
      } else {
        delete item.gaze.look_at_mm;
        item.gaze.ahead = true;
      }
      view.render(rows(), model.end_s || duration(model));
      schedulePreview();
    });
    const [px, py] = gazePad(item.gaze);
    pad.place(px, py);
    clear(inspector, h("div.card", {}, h("div.card-head", {}, h("h3", {}, "Gaze key"), h("span.grow"), del), h("div.form-row", {}, h("label", {}, "time ", time, " s")), h("p.muted", {}, "Drag where the head should look (600 mm ahead); double-click: straight ahead."), pad.el));
  } else if (item.clip.entry.say != null) {
    const text = h("input#say-text", { type: "text", size: "40", maxlength: "2000", value: String(item.clip.entry.say), title: "the words; the mouth's visemes come from espeak-ng's phonemes" });
    text.addEventListener("change", () => {
      item.clip.entry.say = text.value.trim() || "Hello.";
      refresh();
      schedulePreview();
    });
    clear(inspector, h("div.card", {}, h("div.card-head", {}, h("h3", {}, "Speech"), h("span.grow"), del), h("div.form-row", {}, h("label", {}, "start ", time, " s"), h("label", {}, "says ", text)), h("p.muted", {}, "Lip sync from the words (espeak-ng, offline): the speech track owns the mouth while it talks; a held expression keeps the rest of the face. Play on the twin or the head to see the visemes.")));
  } else {
    const lib = h("select#clip-lib", {}, ctx.head.expressions.map((n) => h("option", { value: n, selected: n === item.clip.entry.library }, n)));
    lib.disabled = !item.clip.entry.library;
    lib.addEventListener("change", () => {
      item.clip.entry.library = lib.value;
      refresh();
      schedulePreview();
    });
    clear(inspector, h("div.card", {}, h("div.card-head", {}, h("h3", {}, `Clip on ${item.clip.track}`), h("span.grow"), del), h("div.form-row", {}, h("label", {}, "start ", time, " s"), item.clip.entry.library ? h("label", {}, "expression ", lib) : h("span.muted", {}, clipText(item.clip.entry)))));
  }
}

function recordCard() {
  board.setValues(ctx.sliders?.values || {});
  return h("div", {}, h("p", {}, h("b", {}, "Recording: "), "move sliders here or on the Live page; a key is written on the face track at most every 0.25 s."), board.el);
}

// ---- record --------------------------------------------------------------------------------------
let lastRecordT = -1;
function startRecording() {
  if (playing) stop();
  if (fields.recSource.value !== "sliders") return startStream();
  recording = { t0: performance.now() - time * 1000, from: time, keys: new Set() };
  lastRecordT = -1;
  fields.rec.classList.add("recording");
  fields.rec.textContent = "■ Stop recording";
  selected = null;
  refresh();
  tick();
}

// A live stream: the server listens, the head follows it, the keys come back reduced (API.md "Record").
async function startStream() {
  const transport = fields.recSource.value;
  try {
    const st = await ctx.api.post("/api/record/start", { transport, port: Math.max(0, Math.min(65535, Number(fields.recPort.value) || 0)), follow: true });
    recording = { stream: st, from: time, poll: null };
    fields.rec.classList.add("recording");
    fields.rec.textContent = "■ Stop recording";
    fields.rec.dataset.port = String(st.port);
    status(`Recording the ${transport.toUpperCase()} stream on ${st.host}:${st.port}: send AU frames there (the head follows them).`);
    recording.poll = setInterval(async () => {
      try {
        const now = await ctx.api.get("/api/record");
        if (now.active) status(`Recording ${transport.toUpperCase()} ${now.host}:${now.port}: ${now.samples} frames, ${now.duration_s.toFixed(2)} s${now.bad ? `, ${now.bad} bad` : ""}.`);
      } catch (err) {
        /* the next poll shows it */
      }
    }, 500);
  } catch (err) {
    status(err.describe ? err.describe() : String(err), true);
    ctx.report(err);
  }
}

async function stopStream() {
  const rec = recording;
  recording = null;
  clearInterval(rec.poll);
  fields.rec.classList.remove("recording");
  fields.rec.textContent = "● Record";
  try {
    const out = await ctx.api.post("/api/record/stop", {});
    const track = keyTrack(model, "face");
    const from = rec.from, to = rec.from + out.duration_s;
    track.keys = track.keys.filter((k) => k.t_s < from - 1e-6 || k.t_s > to + 1e-6); // recorded over
    for (const k of out.keys) track.keys.push({ t_s: Math.round((from + k.t_s) * 1000) / 1000, pose: { ...k.pose }, easing: k.easing });
    sortKeys(track);
    if (model.end_s != null && to + 0.5 > model.end_s) model.end_s = Math.ceil((to + 0.5) * 10) / 10;
    refresh();
    status(`Recorded ${out.samples} stream frames into ${out.keys.length} keys on the face track (${fmt(from, 2)}–${fmt(to, 2)} s, within ${out.tolerance} of every AU).`);
    statusLine.dataset.recorded = String(out.keys.length);
  } catch (err) {
    status(err.describe ? err.describe() : String(err), true);
    ctx.report(err);
  }
}

function stopRecording() {
  if (recording?.stream) return stopStream();
  const last = keyTrack(model, "face").keys.at(-1);
  if (last && model.end_s != null && last.t_s + 0.5 > model.end_s) model.end_s = Math.ceil((last.t_s + 0.5) * 10) / 10;
  recording = null;
  fields.rec.classList.remove("recording");
  fields.rec.textContent = "● Record";
  refresh();
  status(`Recorded keys on the face track up to ${time.toFixed(2)} s.`);
}

function recordPose(values) {
  const t = Math.round(((performance.now() - recording.t0) / 1000) * 100) / 100;
  const track = keyTrack(model, "face");
  if (lastRecordT >= 0 && t - lastRecordT < 0.25) {
    const last = track.keys.find((k) => Math.abs(k.t_s - lastRecordT) < 1e-6);
    if (last) last.pose = { ...values };
  } else {
    const since = lastRecordT >= 0 ? lastRecordT : recording.from - 1e-6;
    track.keys = track.keys.filter((k) => recording.keys.has(k) || k.t_s <= since || k.t_s > t); // recorded over
    const key = { t_s: t, pose: { ...values }, easing: "linear" };
    recording.keys.add(key);
    track.keys.push(key);
    sortKeys(track);
    lastRecordT = t;
  }
  if (!ctx.live.send({ type: "set_aus", aus: values, transition_s: 0.1, merge: true })) {
    ctx.api.post("/api/aus", { aus: values, transition_s: 0.1, merge: true }).catch(() => {});
  }
  view.render(rows(), Math.max(model.end_s || 0, duration(model)));
}

// ---- play / scrub --------------------------------------------------------------------------------
function seek(t) {
  time = Math.max(0, t);
  view.setTime(time);
  fields.time.textContent = `${time.toFixed(2)} s`;
  if (!playing || playing.on === "twin") schedulePreview();
}

function tick() {
  if (!playing && (!recording || recording.stream)) return;
  const ref = playing || recording;
  let t = (performance.now() - ref.t0) / 1000;
  const end = model.end_s || duration(model);
  if (playing && t > end) {
    if (fields.loop.checked) {
      playing.t0 = performance.now();
      t = 0;
    } else {
      stop({ release: false }); // the head holds the last pose, as `servoface play` leaves it
      seek(end);
      return;
    }
  }
  time = t;
  view.setTime(t);
  fields.time.textContent = `${t.toFixed(2)} s`;
  if (playing && playing.on === "twin") schedulePreview();
  requestAnimationFrame(tick);
}

async function play() {
  const on = fields.target.value;
  const doc = toDocument(model);
  if (on === "head") {
    try {
      await ctx.api.post("/api/play", { document: doc, track: "face", loop: fields.loop.checked });
    } catch (err) {
      ctx.report(err);
      return;
    }
    time = 0;
  } else if (time >= (model.end_s || duration(model)) - 0.01) time = 0;
  playing = { on, t0: performance.now() - time * 1000 };
  fields.play.textContent = "■ Stop";
  status(on === "head" ? "Playing on the head (every frame through the twin gate)." : "Playing on the twin (no servo moves).");
  tick();
}

/** Stop the playhead; `release` (the Stop button) also stops what plays on the head's tracks. */
function stop({ release = true } = {}) {
  if (release && playing && playing.on === "head") {
    const tracks = new Set(["face", ...model.tracks.map((t) => t.track), ...model.clips.map((c) => c.track)]);
    for (const track of tracks) ctx.api.post("/api/stop", { track, hold: false, release_s: 0.3 }).catch(() => {});
  }
  playing = null;
  fields.play.textContent = "▶ Play";
}

const schedulePreview = throttle(() => {
  previewWanted = time;
  pumpPreview();
}, 50);

async function pumpPreview() {
  if (previewBusy || previewWanted == null) return;
  const t = previewWanted;
  previewWanted = null;
  previewBusy = true;
  try {
    const blob = await ctx.api.post("/api/scripts/preview", { document: toDocument(model), t_s: Math.round(t * 1000) / 1000, which: "achievable" });
    const url = URL.createObjectURL(blob);
    preview.src = url;
    preview.dataset.t = String(t);
    if (previewUrl) URL.revokeObjectURL(previewUrl);
    previewUrl = url;
    previewNote.textContent = "";
  } catch (err) {
    // the script as it stands does not build (say where), or the studio runs without renders
    previewNote.textContent = err.describe ? err.describe() : String(err);
    previewNote.classList.toggle("error", !!err.field);
  } finally {
    previewBusy = false;
    if (previewWanted != null) pumpPreview();
  }
}

function status(text, error = false) {
  if (text) statusLine.textContent = text;
  statusLine.classList.toggle("error", error);
  statusLine.dataset.error = error ? "1" : "";
}

// ---- files ---------------------------------------------------------------------------------------
async function loadList() {
  try {
    const { scripts, shipped } = await ctx.api.get("/api/scripts");
    clear(
      fields.list,
      h("option", { value: "" }, "open a script…"),
      scripts.length ? h("optgroup", { label: "scripts folder" }, scripts.map((n) => h("option", { value: n }, n))) : null,
      h("optgroup", { label: "shipped" }, shipped.map((n) => h("option", { value: n }, n))),
    );
  } catch (err) {
    ctx.report(err);
  }
}

async function load(name) {
  try {
    const file = name.endsWith(".toml") ? name : `${name}.toml`; // a shipped script by its file name
    const res = await ctx.api.get(`/api/scripts/${encodeURIComponent(file)}`);
    model = fromDocument(res.document);
    if (!model.tracks.length) keyTrack(model, "face");
    selected = null;
    fields.name.value = file;
    refresh();
    seek(0);
    status(`Loaded ${name}: ${res.summary.end_s} s, tracks ${res.summary.tracks.join(", ")}.`);
  } catch (err) {
    ctx.report(err);
  }
  fields.list.value = "";
}

async function save() {
  const name = fields.name.value.trim();
  try {
    const res = await ctx.api.put(`/api/scripts/${encodeURIComponent(name)}`, { document: toDocument(model) });
    status(`Saved ${res.path} (${res.summary.end_s} s): play it with  servoface play ${res.path} --head ${ctx.head.name}`);
    statusLine.dataset.saved = res.path;
    loadList();
  } catch (err) {
    status(err.describe ? err.describe() : String(err), true);
    ctx.report(err);
  }
}

function newTimeline() {
  stop();
  model = fromDocument(emptyDocument(ctx.head.face_type));
  keyTrack(model, "face");
  selected = null;
  refresh();
  seek(0);
}

export function show() {
  schedulePreview();
}

export function hide() {
  if (recording) stopRecording();
}
