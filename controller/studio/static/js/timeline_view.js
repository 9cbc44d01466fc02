// The timeline: a ruler, one row per track (keyframes as diamonds, clips as blocks), a playhead.
// Text on the timeline (a clip's label, a row's text, the ruler's seconds) is drawn over the playhead on
// a background of its own, so the line never cuts a word (studio.css, "timeline layers").
// Click a key to select it, drag it to move it in time; double-click an empty row to add a key;
// click or drag on the ruler to scrub.

import { h } from "./dom.js";

const X0 = 12; // px before 0 s, so a key at 0 s shows whole

export class TimelineView {
  constructor({ onSelect, onMove, onAdd, onScrub }) {
    this.cb = { onSelect, onMove, onAdd, onScrub };
    this.pxPerS = 160;
    this.duration = 3;
    this.time = 0;
    this.selected = null;
    this.ruler = h("div.tl-ruler");
    this.rows = h("div.tl-rows");
    this.playhead = h("div.tl-playhead");
    this.canvas = h("div.tl-canvas", {}, this.ruler, this.rows, this.playhead);
    this.labels = h("div.tl-labels", {}, h("div.tl-label.ruler-label", {}, "time (s)"));
    this.el = h("div.timeline", {}, this.labels, h("div.tl-scroll", {}, this.canvas));
    this.scrubbing = false;
    this.ruler.addEventListener("pointerdown", (ev) => {
      this.ruler.setPointerCapture(ev.pointerId);
      this.scrubbing = true;
      this.scrubTo(ev);
    });
    this.ruler.addEventListener("pointermove", (ev) => this.scrubbing && this.scrubTo(ev));
    this.ruler.addEventListener("pointerup", () => (this.scrubbing = false));
  }

  timeAt(ev) {
    const r = this.canvas.getBoundingClientRect();
    return Math.max(0, (ev.clientX - r.left - X0) / this.pxPerS);
  }

  scrubTo(ev) {
    this.cb.onScrub(Math.round(this.timeAt(ev) * 100) / 100);
  }

  /** rows: [{id, label, kind: "keys"|"clips"|"toggle", items: [{id, t_s, end_s?, text?}], hint}] */
  render(rows, duration) {
    this.duration = duration;
    const width = Math.max(600, X0 + (duration + 1) * this.pxPerS);
    this.canvas.style.width = `${width}px`;
    this.ruler.replaceChildren();
    const step = this.pxPerS >= 120 ? 0.25 : 0.5;
    for (let t = 0; t <= duration + 1 + 1e-9; t += step) {
      const major = Math.abs(t - Math.round(t)) < 1e-9;
      this.ruler.append(h(`div.tick${major ? ".major" : ""}`, { style: `left:${X0 + t * this.pxPerS}px` }, major ? h("span", {}, `${Math.round(t)} s`) : null));
    }
    this.ruler.append(h("div.tl-end", { style: `left:${X0 + duration * this.pxPerS}px`, title: "end of the script" }));
    this.labels.replaceChildren(h("div.tl-label.ruler-label", {}, "time (s)"));
    this.rows.replaceChildren();
    for (const row of rows) {
      this.labels.append(h("div.tl-label", {}, h("b", {}, row.label), row.hint ? h("span.muted", {}, row.hint) : null));
      const el = h(`div.tl-row.${row.kind}`, { dataset: { row: row.id } });
      if (row.kind !== "toggle") {
        el.addEventListener("dblclick", (ev) => {
          if (ev.target === el) this.cb.onAdd(row.id, Math.round(this.timeAt(ev) * 100) / 100);
        });
      }
      for (const item of row.items) el.append(this.item(row, item));
      if (row.kind === "toggle") el.append(h("div.tl-toggle", {}, row.text || ""));
      this.rows.append(el);
    }
    this.setTime(this.time);
  }

  item(row, item) {
    const sel = this.selected && this.selected.row === row.id && this.selected.id === item.id;
    let el;
    if (item.end_s != null) {
      el = h("div.tl-clip", { style: `left:${X0 + item.t_s * this.pxPerS}px;width:${Math.max(18, (item.end_s - item.t_s) * this.pxPerS)}px`, title: item.text }, h("span.tl-text", {}, item.text));
    } else {
      el = h("div.tl-key", { style: `left:${X0 + item.t_s * this.pxPerS}px`, title: `${item.t_s.toFixed(2)} s${item.text ? " · " + item.text : ""}` });
    }
    el.classList.toggle("selected", !!sel);
    el.dataset.key = String(item.id);
    el.addEventListener("pointerdown", (ev) => {
      ev.stopPropagation();
      el.setPointerCapture(ev.pointerId);
      this.selected = { row: row.id, id: item.id };
      this.cb.onSelect(row.id, item.id);
      const x0 = ev.clientX, t0 = item.t_s;
      let moved = false;
      const move = (e) => {
        const t = Math.max(0, Math.round((t0 + (e.clientX - x0) / this.pxPerS) * 100) / 100);
        if (Math.abs(e.clientX - x0) > 3) moved = true;
        if (moved) {
          el.style.left = `${X0 + t * this.pxPerS}px`;
          el.dataset.t = String(t);
        }
      };
      const up = () => {
        el.removeEventListener("pointermove", move);
        el.removeEventListener("pointerup", up);
        if (moved) this.cb.onMove(row.id, item.id, Number(el.dataset.t));
      };
      el.addEventListener("pointermove", move);
      el.addEventListener("pointerup", up);
    });
    return el;
  }

  setTime(t) {
    this.time = t;
    this.playhead.style.left = `${X0 + t * this.pxPerS}px`;
  }
}
