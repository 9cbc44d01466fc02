// A square pad: drag the dot to look there (pad coordinates -1..1, +y up); double-click looks ahead.

import { h, throttle } from "./dom.js";

export class GazePad {
  constructor(onGaze) {
    this.dot = h("div.gaze-dot");
    this.el = h("div.gaze-pad", { title: "drag to look; double-click: straight ahead" }, h("div.gaze-cross"), this.dot);
    const send = throttle((px, py) => onGaze([px, py]), 60);
    const move = (ev) => {
      const r = this.el.getBoundingClientRect();
      const px = Math.max(-1, Math.min(1, ((ev.clientX - r.left) / r.width) * 2 - 1));
      const py = Math.max(-1, Math.min(1, 1 - ((ev.clientY - r.top) / r.height) * 2));
      this.place(px, py);
      send(Math.round(px * 100) / 100, Math.round(py * 100) / 100);
    };
    this.el.addEventListener("pointerdown", (ev) => {
      this.el.setPointerCapture(ev.pointerId);
      move(ev);
      this.el.addEventListener("pointermove", move);
    });
    this.el.addEventListener("pointerup", () => this.el.removeEventListener("pointermove", move));
    this.el.addEventListener("dblclick", () => {
      this.place(0, 0);
      onGaze(null);
    });
    this.place(0, 0);
  }

  place(px, py) {
    this.dot.style.left = `${(px + 1) * 50}%`;
    this.dot.style.top = `${(1 - py) * 50}%`;
  }
}
