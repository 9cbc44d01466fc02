// AU sliders grouped by face region. Sided AUs show one linked slider (the plain name drives both
// sides) or, split, one per side (NAMEL / NAMER). Dog (DFACS) sliders are signed: left of the centre
// mark is the counter AU.

import { h } from "./dom.js";
import { groupByRegion, regionTitle } from "./regions.js";

export class SliderBoard {
  /** onChange(aus) with {name: value} for what the user moved; onRelease(names) to let AUs go. */
  constructor(head, { onChange, onRelease }) {
    this.head = head;
    this.onChange = onChange;
    this.onRelease = onRelease;
    this.split = new Set(); // regions shown split L/R
    this.inputs = new Map(); // AU name -> input element
    this.dragging = new Set();
    this.touched = new Map(); // AU name -> when the user last moved it (state pushes lag behind)
    this.values = {}; // what this board last asked for
    this.el = h("div.slider-board");
    this.render();
  }

  render() {
    this.el.replaceChildren();
    this.inputs.clear();
    for (const [region, aus] of groupByRegion(this.head)) this.el.append(this.card(region, aus));
  }

  card(region, aus) {
    const split = this.split.has(region);
    const hasSided = aus.some((a) => a.sided);
    const names = [];
    const body = h("div.sliders");
    for (const au of aus) {
      const sides = au.sided && split ? ["L", "R"] : [""];
      for (const side of sides) {
        const name = au.name + side;
        names.push(name);
        body.append(this.slider(au, name, side));
      }
    }
    const linkBtn = hasSided
      ? h(
          "button.chip",
          {
            title: split ? "link left and right: one slider per AU" : "split left and right: a slider per side",
            onclick: () => {
              split ? this.split.delete(region) : this.split.add(region);
              this.render();
            },
            dataset: { region, action: "split" },
          },
          split ? "L | R" : "L = R",
        )
      : null;
    const releaseBtn = h(
      "button.chip",
      { title: "let these AUs go (back to what else plays)", onclick: () => this.release(names) },
      "release",
    );
    return h(
      "div.card.region",
      { dataset: { region } },
      h("div.card-head", {}, h("h3", {}, regionTitle(region)), h("span.grow"), linkBtn, releaseBtn),
      body,
    );
  }

  slider(au, name, side) {
    const signed = au.min < 0;
    const value = h("span.value", {}, "0.00");
    const input = h("input", {
      type: "range",
      min: String(au.min),
      max: String(au.max),
      step: "0.01",
      value: "0",
      "aria-label": `${name} ${au.label}`,
      dataset: { au: name },
    });
    const show = () => {
      const v = Number(input.value);
      value.textContent = v.toFixed(2);
      row.classList.toggle("active", Math.abs(v) > 0.005);
      if (signed) {
        const pct = ((v - au.min) / (au.max - au.min)) * 100; // filled from the centre (0) to the value
        input.style.setProperty("--lo", `${Math.min(50, pct)}%`);
        input.style.setProperty("--hi", `${Math.max(50, pct)}%`);
      }
    };
    input.addEventListener("pointerdown", () => this.dragging.add(name));
    const end = () => this.dragging.delete(name);
    input.addEventListener("pointerup", end);
    input.addEventListener("change", end);
    input.addEventListener("input", () => {
      show();
      this.values[name] = Number(input.value);
      this.touched.set(name, performance.now());
      this.onChange({ [name]: Number(input.value) });
    });
    input.addEventListener("dblclick", () => {
      input.value = "0";
      input.dispatchEvent(new Event("input"));
    });
    const sideTag = side ? h("span.side", {}, side === "L" ? "left" : "right") : null;
    const row = h(
      `div.slider${signed ? ".signed" : ""}`,
      { title: `${name}: ${au.label}${signed ? " (left of centre: the counter AU)" : ""}` },
      h("label", {}, h("span.au", {}, name), h("span.label", {}, au.label), sideTag),
      input,
      value,
    );
    row.show = show;
    input.row = row;
    this.inputs.set(name, input);
    show();
    return row;
  }

  release(names) {
    for (const name of names) {
      const input = this.inputs.get(name);
      delete this.values[name];
      if (input) {
        input.value = "0";
        input.row.show();
      }
    }
    this.onRelease(names);
  }

  /** Show what the studio track holds now (from the state), except sliders being dragged. */
  sync(aus) {
    for (const [name, input] of this.inputs) {
      if (this.dragging.has(name) || performance.now() - (this.touched.get(name) || -1e9) < 1500) continue;
      const v = aus && name in aus ? aus[name] : 0;
      if (Math.abs(Number(input.value) - v) > 0.004) {
        input.value = String(v);
        input.row.show();
      }
    }
  }

  /** Show only these AU sliders (null: all); a region with none of them is hidden. */
  showOnly(names) {
    const keep = names ? new Set(names) : null;
    for (const [name, input] of this.inputs) input.row.hidden = !!keep && !keep.has(name);
    for (const card of this.el.querySelectorAll(".region")) {
      card.hidden = !!keep && ![...card.querySelectorAll(".slider")].some((row) => !row.hidden);
    }
  }

  /** Show exactly these values (a keyframe's pose), whatever the user touched. */
  setValues(aus) {
    this.values = { ...(aus || {}) };
    this.touched.clear();
    for (const [name, input] of this.inputs) {
      input.value = String(this.values[name] || 0);
      input.row.show();
    }
  }

  reset() {
    this.values = {};
    this.sync({});
  }
}
