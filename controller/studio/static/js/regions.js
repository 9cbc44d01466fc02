// Face regions for grouping AU sliders. The server tags every AU with its region (GET /api/head);
// these are the titles and the order shown.

export const REGION_TITLES = {
  brows: "Brows",
  lids: "Lids",
  eyes: "Eyes",
  nose: "Nose",
  cheeks: "Cheeks",
  lips: "Lips",
  jaw: "Jaw",
  tongue: "Tongue",
  ears: "Ears",
  head: "Head",
};

export function groupByRegion(head) {
  const order = head.regions && head.regions.length ? head.regions : Object.keys(REGION_TITLES);
  const groups = new Map(order.map((r) => [r, []]));
  for (const au of head.aus) {
    if (!groups.has(au.region)) groups.set(au.region, []);
    groups.get(au.region).push(au);
  }
  for (const [region, list] of groups) if (!list.length) groups.delete(region);
  return groups;
}

export function regionTitle(region) {
  return REGION_TITLES[region] || region.charAt(0).toUpperCase() + region.slice(1);
}

/** "AU12" -> 12, for sorting. */
export function auNumber(name) {
  return parseInt(name.replace(/^AU/, ""), 10);
}
