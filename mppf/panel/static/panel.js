// mppf operator's panel: the live stream (server-sent events), the heat maps, STOP.
// No external code: plain DOM. Only STOP is ever sent to the server.
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const SIDES = ["upper", "lower"];
  const KINDS = ["target", "actual"];
  const PARKED = "#dde1e5"; // a punch at its parking height
  const STALE_MS = 2000; // no message for this long: the panel server itself is not answering
  const live = $("live");
  const cmap = live ? live.dataset.viridis.split(",") : [];
  let lastMessage = 0;
  let historyRev = null;
  let snapshot = null;
  let selected = null;

  function rgb(hex) { return [1, 3, 5].map((k) => parseInt(hex.slice(k, k + 2), 16)); }
  function colour(v, lo, hi) {
    if (v === null || !isFinite(v)) return "#c8c8c8";
    const t = hi <= lo ? 0.5 : Math.min(1, Math.max(0, (v - lo) / (hi - lo)));
    const pos = t * (cmap.length - 1);
    const k = Math.min(Math.floor(pos), cmap.length - 2);
    const f = pos - k;
    const a = rgb(cmap[k]), b = rgb(cmap[k + 1]);
    return "#" + a.map((x, i) => Math.round(x + f * (b[i] - x)).toString(16).padStart(2, "0")).join("");
  }
  function ink(hex) { const [r, g, b] = rgb(hex); return 0.299 * r + 0.587 * g + 0.114 * b > 140 ? "#000" : "#fff"; }
  function short(v) {
    if (v === null || !isFinite(v)) return "-";
    return Math.abs(v) >= 99.95 ? v.toFixed(0) : v.toFixed(1);
  }
  function parked(v, side) {
    const park = snapshot.live.park_mm ? snapshot.live.park_mm[side] : null;
    return v !== null && park !== null && Math.abs(v - park) < 0.05;
  }
  function scale(side) {
    // the colour scale spans the targets of the punches in use (parked punches would squeeze it to two
    // colours, punches on their way would stretch it); actual values beyond it show in its end colours
    const span = (kinds) => {
      let lo = Infinity, hi = -Infinity;
      for (const kind of kinds) {
        for (const row of snapshot.live.matrices[side][kind]) for (const v of row) {
          if (v !== null && !parked(v, side)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
        }
      }
      return [lo, hi];
    };
    let [lo, hi] = span(["target"]);
    if (!isFinite(lo)) [lo, hi] = span(["actual"]);
    if (!isFinite(lo)) return [0, 1];
    if (hi - lo < 10) { const m = (lo + hi) / 2; lo = m - 5; hi = m + 5; }
    return [lo, hi];
  }

  function drawMaps(m, base) {
    for (const side of SIDES) {
      const [lo, hi] = scale(side);
      const lt = $(side + "-scale-lo"), ht = $(side + "-scale-hi");
      if (lt) lt.textContent = lo.toFixed(1);
      if (ht) ht.textContent = hi.toFixed(1);
      for (const kind of KINDS) {
        const grid = m[side][kind];
        for (let r = 0; r < grid.length; r++) for (let c = 0; c < grid[r].length; c++) {
          const id = `${side}-${kind}-r${r + base}-c${c + base}`;
          const cell = $(id);
          if (!cell) continue;
          const v = grid[r][c];
          const text = v === null ? "" : v.toFixed(2);
          if (cell.dataset.mm === text && cell.dataset.lo === String(lo) && cell.dataset.hi === String(hi)) continue;
          const park = parked(v, side);
          const fill = park ? PARKED : colour(v, lo, hi);
          cell.setAttribute("fill", fill);
          cell.dataset.mm = text; cell.dataset.lo = String(lo); cell.dataset.hi = String(hi);
          cell.firstChild.textContent = `${side} ${cell.dataset.name} ${kind}: ${short(v)} mm`;
          const label = $(`${side}-${kind}-v-r${r + base}-c${c + base}`);
          if (label) { label.textContent = park ? "P" : short(v); label.setAttribute("fill", ink(fill)); }
        }
        drawFlags(`${side}-${kind}-flags`, m[side].flags);
      }
    }
  }

  function drawFlags(id, flags) {
    const g = $(id);
    if (!g) return;
    const key = JSON.stringify(flags);
    if (g.dataset.key === key) return;
    g.dataset.key = key;
    const cell = parseFloat(g.dataset.cell), left = parseFloat(g.dataset.left), top = parseFloat(g.dataset.top);
    const rows = flags.length, ns = "http://www.w3.org/2000/svg";
    while (g.firstChild) g.removeChild(g.firstChild);
    for (let r = 0; r < rows; r++) for (let c = 0; c < flags[r].length; c++) {
      const kind = flags[r][c];
      if (!kind) continue;
      const w = 0.14 * cell, x = left + c * cell, y = top + (rows - 1 - r) * cell;
      const rect = document.createElementNS(ns, "rect");
      for (const [k, v] of Object.entries({ x: x + w / 2, y: y + w / 2, width: cell - w, height: cell - w,
        fill: "none", stroke: kind === "faulted" ? "#e00000" : "#ff8c00", "stroke-width": w })) rect.setAttribute(k, v);
      if (kind !== "faulted") rect.setAttribute("stroke-dasharray", `${0.25 * cell} ${0.12 * cell}`);
      rect.setAttribute("class", "flag flag-" + kind);
      g.appendChild(rect);
    }
  }

  function drawFlagged(s) {
    const list = $("flagged");
    if (!list) return;
    const n = $("n-flagged");
    n.textContent = s.n_flagged;
    n.className = "count" + (s.n_flagged ? " alarm" : "");
    const key = JSON.stringify(s.flagged);
    if (list.dataset.key === key) return;
    list.dataset.key = key;
    list.innerHTML = "";
    for (const f of s.flagged) {
      const li = document.createElement("li");
      li.className = f.kind;
      li.textContent = `${f.name}: ${f.kind}, target ${f.target_mm.toFixed(2)} mm, actual ${f.actual_mm.toFixed(2)} mm`;
      list.appendChild(li);
    }
    if (s.n_flagged > s.flagged.length) {
      const li = document.createElement("li");
      li.textContent = `and ${s.n_flagged - s.flagged.length} more`;
      list.appendChild(li);
    }
  }

  function drawReadout() {
    const box = $("readout");
    if (!box || !selected || !snapshot || !snapshot.live.matrices) return;
    const m = snapshot.live.matrices[selected.side];
    const t = m.target[selected.r][selected.c], a = m.actual[selected.r][selected.c];
    box.textContent = `${selected.side} ${selected.name}: target ${short(t)} mm, actual ${short(a)} mm` +
      (m.flags[selected.r][selected.c] ? ` (${m.flags[selected.r][selected.c]})` : "");
  }

  function setText(id, text, alarm) {
    const el = $(id);
    if (!el) return;
    el.textContent = text;
    el.classList.toggle("alarm", !!alarm);
  }

  function drawStatus(s) {
    const state = $("state");
    state.textContent = s.state;
    state.className = "chip chip-" + s.state.toLowerCase().replace(/[^a-z]/g, "").replace("linklost", "lost");
    state.title = s.plc_state ? "PLC state " + s.plc_state : "";
    const link = $("link");
    if (s.link.ok) {
      link.textContent = `link ok: ${s.link.url}` + (s.heartbeat_stale ? " · PLC HEARTBEAT STALE" : "");
      link.className = "link" + (s.heartbeat_stale ? " lost" : "");
    } else if (!s.link.url) {
      link.textContent = s.link.error; // no PLC known yet: nothing was lost
      link.className = "link noplc";
    } else {
      link.textContent = `LINK LOST to ${s.link.url} (${s.link.lost_s} s): ${s.link.error}`;
      link.className = "link lost";
    }
    setText("link-detail", s.link.ok ? `${s.link.url} (${s.link.source})` : `${s.link.error}`, !s.link.ok);
    setText("fault", s.fault ? (s.fault.code ? `${s.fault.code}: ${s.fault.text}` : "none") : "-", s.fault && s.fault.code);
    setText("refusal", s.refusal ? (s.refusal.code ? `${s.refusal.code}: ${s.refusal.text}` : "none") : "-");
    setText("plc-state", s.plc_state || "-");
    setText("sequence", s.sequence ? `validated ${s.sequence.validated} · moved ${s.sequence.motion}` : "-");
    setText("owner", s.owner === null || s.owner === undefined ? "-" :
      (s.owner ? "master 0x" + s.owner.toString(16).toUpperCase().padStart(8, "0") : "none"));
    setText("stops", s.stops ? `${s.stops.count}${s.stops.count ? ", last: " + s.stops.cause : ""}` : "-");
    const pct = s.progress_pct;
    setText("progress", pct === null ? (s.moving ? "moving" : "-") : `${pct.toFixed(0)} % done${s.moving ? ", moving" : ", at rest"}`);
    const bar = $("progress-bar");
    if (bar) bar.style.width = (pct === null ? 0 : pct) + "%";
    if (live) live.classList.toggle("stale", !s.link.ok);
  }

  function onMessage(ev) {
    lastMessage = Date.now();
    snapshot = JSON.parse(ev.data);
    const s = snapshot.live;
    drawStatus(s);
    $("loop-brief").textContent = snapshot.loop || "";
    if (live && s.matrices && !document.querySelector("svg.heat")) {
      location.reload(); // the press description came after the page: draw its matrices
      return;
    }
    if (live && s.matrices) {
      drawMaps(s.matrices, parseInt(document.body.dataset.base || "1", 10));
      drawFlagged(s);
      drawReadout();
    }
    if (historyRev !== null && snapshot.history_rev !== historyRev) reloadView();
    historyRev = snapshot.history_rev;
  }

  async function reloadView() {
    const view = $("view");
    if (!view || ["live", "login"].includes(view.dataset.view)) return;
    try {
      const reply = await fetch(location.href, { headers: { "X-Fragment": "1" }, credentials: "same-origin" });
      if (reply.ok) view.innerHTML = await reply.text();
    } catch (e) { /* the next change tries again */ }
  }

  function banner(text, bad) {
    const b = $("banner");
    b.textContent = text;
    b.className = "banner" + (bad ? " bad" : "");
    b.hidden = false;
    clearTimeout(b._timer);
    b._timer = setTimeout(() => { b.hidden = true; }, bad ? 30000 : 10000);
  }

  async function stop() {
    const button = $("stop");
    button.disabled = true;
    try {
      const reply = await fetch("/stop", { method: "POST", credentials: "same-origin",
        headers: { "Content-Type": "application/json" }, body: "{}" });
      const doc = await reply.json();
      banner(doc.message, !doc.ok);
    } catch (e) {
      banner("STOP NOT SENT: the panel server does not answer; stop the press at the machine", true);
    } finally {
      button.disabled = false;
    }
  }

  function onCellTouch(ev) {
    const cell = ev.target.closest ? ev.target.closest("rect.cell") : null;
    if (!cell || !cell.id) return;
    const m = cell.id.match(/^(upper|lower)-(target|actual)-r(\d+)-c(\d+)$/);
    if (!m) return;
    const base = parseInt(document.body.dataset.base || "1", 10);
    selected = { side: m[1], r: parseInt(m[3], 10) - base, c: parseInt(m[4], 10) - base, name: cell.dataset.name };
    drawReadout();
  }

  function watchdog() {
    if (Date.now() - lastMessage > STALE_MS) {
      const state = $("state");
      state.textContent = "NO DATA";
      state.className = "chip chip-lost";
      const link = $("link");
      link.textContent = "NO UPDATE from the panel server: the page shows old values";
      link.className = "link lost";
    }
  }

  $("stop").addEventListener("click", stop);
  document.addEventListener("click", onCellTouch);
  const source = new EventSource("/events");
  source.onmessage = onMessage;
  setInterval(watchdog, 500);
})();
