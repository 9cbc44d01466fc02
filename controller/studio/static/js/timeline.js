// The Author page's model of a script: keyframe tracks, a gaze track, expression clips and blinks, read
// from and written back to the script document (the TOML of `servoface play` as JSON, API.md). What the
// page does not edit (other expressions, poses, blend rules, idle, gaze set-up ...) is kept as it was.

export const EASINGS = ["linear", "ease_in_out", "min_jerk", "step"];
const copy = (v) => (v === undefined ? undefined : JSON.parse(JSON.stringify(v)));
const round = (v, d = 3) => Math.round(v * 10 ** d) / 10 ** d;

export function emptyDocument(face, title = "Studio timeline") {
  return { script: { face, title, end_s: 3.0 }, expressions: {}, play: [] };
}

/** document -> model */
export function fromDocument(doc) {
  const d = copy(doc) || {};
  const expressions = d.expressions || {};
  const poses = d.poses || {};
  const model = {
    doc: d,
    face: d.script?.face || "human",
    title: d.script?.title || "",
    end_s: d.script?.end_s ?? null,
    tracks: [],
    clips: [],
    gaze: (d.gaze || []).map((g) => ({ ...copy(g) })),
    blink: d.blink ? d.blink.enabled !== false : false,
  };
  (d.play || []).forEach((entry, i) => {
    const spec = entry.expression && expressions[entry.expression];
    const track = entry.track || (entry.say != null ? "speech" : "face"); // a speech cue plays on "speech
    if (spec && Array.isArray(spec.keyframes) && !model.tracks.some((t) => t.expression === entry.expression)) {
      model.tracks.push({
        track,
        index: i,
        entry: copy(entry),
        expression: entry.expression,
        at_s: entry.at_s ?? 0,
        keys: spec.keyframes.map((k) => ({
          t_s: (entry.at_s ?? 0) + (k.t_s ?? 0),
          pose: typeof k.pose === "string" ? { ...(poses[k.pose] || {}) } : { ...(k.pose || {}) },
          poseName: typeof k.pose === "string" ? k.pose : undefined,
          easing: k.easing,
        })),
      });
    } else {
      model.clips.push({ index: i, entry: copy(entry), track });
    }
  });
  return model;
}

/** The keyframe track on `track` (made if missing). */
export function keyTrack(model, track = "face") {
  let t = model.tracks.find((x) => x.track === track);
  if (!t) {
    let name = `${track}_keys`;
    for (let n = 2; model.doc.expressions && model.doc.expressions[name]; n++) name = `${track}_keys_${n}`;
    t = { track, index: 1e6 + model.tracks.length, entry: null, expression: name, at_s: 0, keys: [] };
    model.tracks.push(t);
  }
  return t;
}

export function sortKeys(track) {
  track.keys.sort((a, b) => a.t_s - b.t_s);
}

export function duration(model) {
  let end = model.end_s || 0;
  for (const t of model.tracks) for (const k of t.keys) end = Math.max(end, k.t_s);
  for (const g of model.gaze) end = Math.max(end, (g.at_s || 0) + 0.5);
  for (const c of model.clips) end = Math.max(end, (c.entry.at_s || 0) + 1);
  return Math.max(end, 1);
}

/** model -> document (the script `servoface play` reads). Only what the page edits changes: a loaded
script saved without edits is the same document. */
export function toDocument(model) {
  const doc = copy(model.doc) || {};
  doc.script = { ...(doc.script || {}), face: model.face };
  if (model.title) doc.script.title = model.title;
  if (model.end_s != null) doc.script.end_s = round(model.end_s);
  const expressions = { ...(doc.expressions || {}) };
  const plays = []; // [index, entry]: the order of the file, new tracks at the end
  for (const t of model.tracks) {
    sortKeys(t);
    if (!t.keys.length) {
      if (!t.entry) continue;
      delete expressions[t.expression];
      continue;
    }
    const at = Math.min(t.at_s ?? 0, t.keys[0].t_s);
    const keys = t.keys.map((k) => {
      const key = { t_s: round(k.t_s - at), pose: k.poseName && samePose(doc.poses?.[k.poseName], k.pose) ? k.poseName : cleanPose(k.pose) };
      if (k.easing) key.easing = k.easing;
      return key;
    });
    if (keys[keys.length - 1].t_s <= 0) keys[keys.length - 1].t_s = 0.001; // a clip needs a length > 0
    expressions[t.expression] = { ...(doc.expressions?.[t.expression] || {}), keyframes: keys };
    const entry = t.entry ? { ...t.entry } : { expression: t.expression };
    entry.at_s = round(at);
    if (!t.entry && t.track !== "face") entry.track = t.track;
    plays.push([t.index, entry]);
  }
  for (const c of model.clips) plays.push([c.index, c.entry]);
  plays.sort((a, b) => a[0] - b[0]);
  if (plays.length || doc.play) doc.play = plays.map(([, e]) => e);
  if (Object.keys(expressions).length || doc.expressions) doc.expressions = expressions;
  if (model.gaze.length) doc.gaze = model.gaze.map((g) => ({ ...g, at_s: round(g.at_s) }));
  else delete doc.gaze;
  const blinking = doc.blink ? doc.blink.enabled !== false : false;
  if (model.blink && !blinking) doc.blink = { ...(doc.blink || {}), enabled: true };
  if (!model.blink && blinking) doc.blink = { ...doc.blink, enabled: false };
  return doc;
}

function cleanPose(pose) {
  const out = {};
  for (const [k, v] of Object.entries(pose || {})) if (Math.abs(v) > 1e-9) out[k] = round(v, 4);
  return out;
}

function samePose(a, b) {
  const x = cleanPose(a), y = cleanPose(b);
  const keys = new Set([...Object.keys(x), ...Object.keys(y)]);
  for (const k of keys) if (Math.abs((x[k] || 0) - (y[k] || 0)) > 1e-6) return false;
  return true;
}

/** Gaze entry -> pad position (-1..1) for drawing; the inverse of the server's pad mapping. */
export function gazePad(entry) {
  if (!entry.look_at_mm) return [0, 0];
  const [x, y, z] = entry.look_at_mm;
  const s = z > 0 ? 600 / z : 1;
  return [Math.max(-1, Math.min(1, (x * s) / 300)), Math.max(-1, Math.min(1, (y * s) / 200))];
}

export function padToPoint([px, py]) {
  return [round(px * 300, 1), round(py * 200, 1), 600.0];
}
