// The live twin: the achievable (gated) face the servos make, and the muscle target beside it on demand.
// Images come over the WebSocket as binary frames; each replaces the last (a slow page skips frames).

import { h } from "./dom.js";

export class TwinView {
  constructor(live, { caption = true } = {}) {
    this.live = live;
    this.urls = {};
    this.seq = { achievable: 0, target: 0 };
    this.imgs = {
      achievable: h("img.twin-img", { alt: "the face the servos make (twin, gated)", dataset: { which: "achievable" } }),
      target: h("img.twin-img", { alt: "the muscle model's target face", dataset: { which: "target" } }),
    };
    this.targetBox = h(
      "figure.twin-fig.target",
      { hidden: true },
      this.imgs.target,
      caption ? h("figcaption", {}, "muscle target") : null,
    );
    this.el = h(
      "div.twin",
      {},
      h("figure.twin-fig", {}, this.imgs.achievable, caption ? h("figcaption", {}, "achievable (what the servos make)") : null),
      this.targetBox,
    );
    live.on("twin-image", (msg) => this.show(msg.which, msg.blob, msg.seq));
  }

  show(which, blob, seq) {
    if (!this.imgs[which]) return;
    const url = URL.createObjectURL(blob);
    const old = this.urls[which];
    this.urls[which] = url;
    this.seq[which] = seq;
    this.imgs[which].src = url;
    this.imgs[which].dataset.seq = String(seq);
    if (old) setTimeout(() => URL.revokeObjectURL(old), 1000);
  }

  set showTarget(on) {
    this.targetBox.hidden = !on;
    this.el.classList.toggle("pair", on);
  }
}

/** The verdict of the latest frame, with its checks and reasons. */
export class VerdictView {
  constructor() {
    this.badge = h("span.verdict", {}, "–");
    this.checks = h("span.checks");
    this.reasons = h("ul.reasons");
    this.el = h("div.verdict-box", {}, h("div.verdict-line", {}, h("span.muted", {}, "twin gate"), this.badge, this.checks), this.reasons);
    this.last = "";
  }

  update(frame) {
    const key = `${frame.verdict}|${(frame.reasons || []).join("|")}`;
    if (key === this.last) return;
    this.last = key;
    this.badge.textContent = frame.verdict;
    this.badge.className = `verdict ${frame.verdict}`;
    this.checks.textContent = (frame.checks || []).join(" · ");
    this.reasons.replaceChildren(...(frame.reasons || []).slice(0, 6).map((r) => h("li", {}, r)));
  }
}
