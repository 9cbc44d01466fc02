// Servos: the chain's telemetry live; manual mode to jog within limits; torque per servo; reboot.

import { h, fmt } from "./dom.js";

let ctx, tbody, manualBox, stepSel, pageEl, visible = false;
let manualPending = 0; // manual-mode requests on their way
const rows = new Map();

export function mount(el, c) {
  ctx = c;
  manualBox = h("input", { type: "checkbox", id: "manual" });
  // while a request is on its way, a state that left the server before it (the page's first GET of the
  // state, a push) must not flip the box back: the box shows the request, then the server's answer
  manualBox.addEventListener("change", () => {
    manualPending += 1;
    ctx.api
      .post("/api/servos/manual", { on: manualBox.checked })
      .then((res) => {
        if (manualPending === 1) showManual(!!res.manual);
      })
      .catch((err) => {
        if (manualPending === 1) showManual(!!(ctx.state && ctx.state.manual));
        ctx.report(err);
      })
      .finally(() => {
        manualPending -= 1;
      });
  });
  stepSel = h(
    "select#jog-step",
    {},
    [1, 5, 10, 25, 50, 100].map((n) => h("option", { value: String(n), selected: n === 10 }, `${n} ticks`)),
  );
  tbody = h("tbody");
  for (const servo of ctx.head.servos) tbody.append(row(servo));
  el.append(
    h(
      "div.card",
      {},
      h(
        "div.card-head",
        {},
        h("h3", {}, "Servo chain"),
        h("span.muted", {}, `${ctx.head.servos.length} servos · telemetry live`),
        h("span.grow"),
        h("label.toggle", { title: "pause the head service loop and lend the bus to this page, to jog servos" }, manualBox, h("span", {}, "manual mode (jog)")),
        h("label", {}, "step ", stepSel),
        h("button.btn", { onclick: () => ctx.api.post("/api/torque", { on: true }).catch(ctx.report) }, "All torque on"),
        h("button.btn.ghost", { onclick: () => ctx.api.post("/api/torque", { on: false }).catch(ctx.report) }, "All torque off"),
      ),
      h(
        "div.table-wrap",
        {},
        h(
          "table.servos",
          {},
          h(
            "thead",
            {},
            h(
              "tr",
              {},
              ["id", "role", "model", "position / limits", "pos", "goal", "load", "current", "temp", "volt", "torque", "faults", "jog", ""].map((t) =>
                h("th", {}, t),
              ),
            ),
          ),
          tbody,
        ),
      ),
    ),
  );
  ctx.live.on("telemetry", (msg) => visible && update(msg.servos));
  pageEl = el;
  ctx.onState((state) => {
    if (manualPending === 0) showManual(!!state.manual);
  });
}

function showManual(on) {
  manualBox.checked = on;
  pageEl.classList.toggle("manual", on);
}

function row(servo) {
  const cells = {};
  const cell = (key, cls = "") => (cells[key] = h(`td${cls}`, {}, "–"));
  const bar = h("div.range-bar", {}, h("div.range-neutral"), (cells.goalMark = h("div.range-goal")), (cells.posMark = h("div.range-pos")));
  const jog = (sign) => () => {
    const delta = sign * Number(stepSel.value);
    ctx.api.post(`/api/servos/${servo.id}/jog`, { delta_tick: delta }).catch(ctx.report);
  };
  const torqueBtn = h("button.chip", {
    dataset: { servo: String(servo.id), action: "torque" },
    onclick: () => ctx.api.post(`/api/servos/${servo.id}/torque`, { on: torqueBtn.dataset.on !== "1" }).catch(ctx.report),
  }, "–");
  cells.torque = h("td", {}, torqueBtn);
  const span = servo.max_tick - servo.min_tick || 1;
  bar.querySelector(".range-neutral").style.left = `${((servo.neutral_tick - servo.min_tick) / span) * 100}%`;
  const tr = h(
    "tr",
    { dataset: { servo: String(servo.id) } },
    h("td.num", {}, servo.id),
    h("td.role", {}, servo.role),
    h("td.muted", {}, servo.model),
    h("td", { title: `limits ${servo.min_tick}..${servo.max_tick}, neutral ${servo.neutral_tick}` }, h("div.bar-cell", {}, h("span.lim", {}, servo.min_tick), bar, h("span.lim", {}, servo.max_tick))),
    cell("pos", ".num"),
    cell("goal", ".num"),
    cell("load", ".num"),
    cell("current", ".num"),
    cell("temp", ".num"),
    cell("volt", ".num"),
    cells.torque,
    cell("faults", ".faults"),
    h(
      "td.jog",
      {},
      h("button.chip", { onclick: jog(-1), title: "jog down (manual mode)", dataset: { servo: String(servo.id), action: "jog-" } }, "−"),
      h("button.chip", { onclick: jog(1), title: "jog up (manual mode)", dataset: { servo: String(servo.id), action: "jog+" } }, "+"),
    ),
    h(
      "td",
      {},
      h("button.chip", {
        title: "reboot and clear its fault (re-configured, goal pinned)",
        onclick: () => ctx.api.post(`/api/servos/${servo.id}/reboot`, {}).catch(ctx.report),
      }, "reboot"),
    ),
  );
  rows.set(servo.id, { tr, cells, servo, torqueBtn, span });
  return tr;
}

function update(servos) {
  for (const t of servos || []) {
    const r = rows.get(t.id);
    if (!r) continue;
    const { cells, servo, span } = r;
    cells.pos.textContent = fmt(t.position_tick);
    cells.goal.textContent = fmt(t.goal_tick);
    cells.load.textContent = t.load_pct == null ? "–" : `${fmt(t.load_pct, 1)} %`;
    cells.current.textContent = t.current_ma == null ? "–" : `${fmt(t.current_ma, 0)} mA`;
    cells.temp.textContent = t.temperature_c == null ? "–" : `${fmt(t.temperature_c, 0)} °C`;
    cells.volt.textContent = t.voltage_v == null ? "–" : `${fmt(t.voltage_v, 1)} V`;
    const hot = t.temperature_c != null && t.temperature_c >= 60;
    cells.temp.classList.toggle("bad", hot);
    r.torqueBtn.textContent = t.torque_on ? "on" : "off";
    r.torqueBtn.dataset.on = t.torque_on ? "1" : "0";
    r.torqueBtn.classList.toggle("on", !!t.torque_on);
    const faults = [...(t.faults || [])];
    if (t.missing) faults.unshift("missing");
    if (t.hardware_error) faults.push(`hw 0x${t.hardware_error.toString(16)}`);
    cells.faults.textContent = faults.join(", ");
    r.tr.classList.toggle("faulted", faults.length > 0);
    const place = (mark, tick) => {
      mark.hidden = tick == null;
      if (tick != null) mark.style.left = `${Math.max(0, Math.min(1, (tick - servo.min_tick) / span)) * 100}%`;
    };
    place(cells.posMark, t.position_tick);
    place(cells.goalMark, t.goal_tick);
  }
}

export function show() {
  visible = true;
  ctx.live.subscribe({ telemetry: true });
  ctx.api.get("/api/servos").then((m) => update(m.servos)).catch(() => {});
}

export function hide() {
  visible = false;
}
