// Live: AU sliders by region, the expression library, the gaze pad, the twin and its verdict.

import { h, fmt, throttle } from "./dom.js";
import { GazePad } from "./gazepad.js";
import { SliderBoard } from "./sliders.js";
import { TwinView, VerdictView } from "./twin.js";

let ctx, twin, verdict, board, visible = false;
const pending = {};

function sendAus() {
  const aus = { ...pending };
  for (const k of Object.keys(pending)) delete pending[k];
  if (!Object.keys(aus).length) return;
  const msg = { type: "set_aus", aus, transition_s: 0.1, merge: true };
  if (!ctx.live.send(msg)) ctx.api.post("/api/aus", { aus, transition_s: 0.1, merge: true }).catch(ctx.report);
}
const flush = throttle(sendAus, 40);

/** "affection_ii" -> "Affection II", "brow_flash" -> "Brow flash". */
function title(name) {
  const words = name.split("_").map((w) => (/^(i|ii|iii|iv|v)$/.test(w) ? w.toUpperCase() : w));
  words[0] = words[0].charAt(0).toUpperCase() + words[0].slice(1);
  return words.join(" ");
}

export function mount(el, c) {
  ctx = c;
  const head = ctx.head;
  twin = new TwinView(ctx.live);
  verdict = new VerdictView();
  ctx.sliderListeners = new Set();
  board = new SliderBoard(head, {
    onChange: (aus) => {
      Object.assign(pending, aus);
      flush();
      for (const fn of ctx.sliderListeners) fn({ ...board.values });
    },
    onRelease: (names) => {
      ctx.api.post("/api/aus/clear", { names, transition_s: 0.3 }).catch(ctx.report);
      for (const fn of ctx.sliderListeners) fn({ ...board.values });
    },
  });
  ctx.sliders = board;

  const stats = h("div.stats.muted#live-stats");
  const targetToggle = h("input", { type: "checkbox", id: "show-target" });
  targetToggle.addEventListener("change", () => {
    twin.showTarget = targetToggle.checked;
    ctx.live.subscribe({ target: targetToggle.checked });
  });

  const intensity = h("input", { type: "range", min: "0", max: "1", step: "0.05", value: "1", id: "expr-intensity" });
  const intensityValue = h("span.value", {}, "1.00");
  intensity.addEventListener("input", () => (intensityValue.textContent = fmt(Number(intensity.value))));
  const holdFor = h("input.num", { type: "number", min: "0", max: "3600", step: "0.5", value: "2", id: "expr-hold" });
  const onStudio = h("input", { type: "checkbox", id: "expr-studio" });
  const express = (name) =>
    ctx.api
      .post("/api/express", {
        name,
        intensity: Number(intensity.value),
        transition_s: 0.5,
        hold_s: Math.max(0, Number(holdFor.value) || 0),
        track: onStudio.checked ? "studio" : "face",
      })
      .catch(ctx.report);
  const buttons = head.expressions.map((name) =>
    h("button.expr", { onclick: () => express(name), dataset: { expression: name } }, title(name)),
  );

  const blink = h("input", { type: "checkbox", id: "alive-blink" });
  const idle = h("input", { type: "checkbox", id: "alive-idle" });
  const alive = () => ctx.api.post("/api/alive", { blink: blink.checked, idle: idle.checked }).catch(ctx.report);
  blink.addEventListener("change", alive);
  idle.addEventListener("change", alive);

  const pad = new GazePad((p) => {
    const body = p ? { pad: p } : { point_mm: null };
    if (!ctx.live.send({ type: "gaze", ...body })) ctx.api.post("/api/gaze", body).catch(ctx.report);
  });

  const neutral = () => {
    board.reset();
    ctx.api.post("/api/neutral", { transition_s: 0.6 }).catch(ctx.report);
  };

  el.append(
    h(
      "div.live-grid",
      {},
      h(
        "div.col.col-twin",
        {},
        h(
          "div.card",
          {},
          h(
            "div.card-head",
            {},
            h("h3", {}, "Twin"),
            h("span.grow"),
            h("label.toggle", {}, targetToggle, h("span", {}, "muscle target beside")),
          ),
          twin.el,
          verdict.el,
          stats,
        ),
        h(
          "div.card.row-card",
          {},
          h("div", {}, h("h3", {}, "Gaze"), pad.el),
          h(
            "div.stack",
            {},
            h("h3", {}, "Alive"),
            h("label.toggle", {}, blink, h("span", {}, "blinks")),
            h("label.toggle", {}, idle, h("span", {}, "idle motion")),
            h("h3", {}, "Pose"),
            h("button.btn", { onclick: neutral, id: "neutral" }, "Ease to neutral"),
            h("button.btn.ghost", { onclick: () => board.release([...board.inputs.keys()]) }, "Release sliders"),
          ),
        ),
      ),
      h(
        "div.col.col-controls",
        {},
        h(
          "div.card",
          {},
          h("div.card-head", {}, h("h3", {}, "Expressions"), h("span.grow"), h("span.muted", {}, head.face_type === "dog" ? "DFACS recipes" : "EMFACS prototypes")),
          h("div.expr-grid", {}, buttons),
          h(
            "div.expr-opts",
            {},
            h("label", {}, "intensity ", intensity, intensityValue),
            h("label", {}, "hold ", holdFor, " s"),
            h("label.toggle", { title: "on the studio track: it owns those AUs over scripts" }, onStudio, h("span", {}, "on the studio track")),
          ),
        ),
        h("div.card-title", {}, h("h2", {}, "Action units"), h("span.muted", {}, head.face_type === "dog" ? "DFACS, signed: left of centre is the counter AU · double-click a slider for 0" : "FACS 0..1 · double-click a slider for 0")),
        board.el,
      ),
    ),
  );

  ctx.live.on("frame", (msg) => visible && verdict.update(msg));
  ctx.onState((state) => {
    const playing = Object.entries(state.tracks || {}).filter(([, t]) => t.state === "running").map(([name, t]) => `${name}: ${t.source}`);
    stats.textContent = `frame ${state.frames} · ${state.late} late · ${state.clients} browser${state.clients === 1 ? "" : "s"} · ${playing.length ? "playing " + playing.join(", ") : "idle"}`;
    const studio = state.tracks && state.tracks.studio;
    board.sync(studio && studio.state !== "empty" ? studio.aus : {});
  });
}

export function show() {
  visible = true;
  ctx.live.subscribe({ twin: true, target: document.getElementById("show-target").checked, frames: true });
}

export function hide() {
  visible = false;
  ctx.live.subscribe({ twin: false, target: false }); // no renders for a page nobody looks at
}
