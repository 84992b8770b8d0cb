// photonlab experiment report: image comparison viewer. No dependencies; works from
// file:// (images by <img>, radiance by <script> files calling PL.hdr).
// URL hash options: #cell=STEM&mode=cell|ref|flip|slide|relerr|signed&ev=N&comp&selftest
"use strict";
(function () {
  const D = PL_DATA;
  const hdrs = {}; // id -> {w, h, f: Float32Array (RGB)}
  const waiting = {}; // id -> [callbacks]
  const imgs = {}; // src -> Image
  const st = { cell: 0, mode: "flip", showRef: false, ev: 0, scale: 1, ox: 0, oy: 0, split: 0.5, mouse: null, comp: false };

  window.PL = {
    hdr(id, w, h, b64) {
      const bin = atob(b64);
      const f = new Float32Array(w * h * 3);
      for (let i = 0; i < w * h; i++) {
        const e = bin.charCodeAt(4 * i + 3);
        const s = e === 0 ? 0 : Math.pow(2, e - 136);
        for (let c = 0; c < 3; c++) f[3 * i + c] = e === 0 ? 0 : (bin.charCodeAt(4 * i + c) + 0.5) * s;
      }
      hdrs[id] = { w, h, f, canvas: null, ev: null };
      (waiting[id] || []).forEach((cb) => cb(hdrs[id]));
      delete waiting[id];
    },
  };

  function loadHdr(id, src, cb, fail) {
    if (hdrs[id]) return cb(hdrs[id]);
    if (waiting[id]) return waiting[id].push(cb);
    waiting[id] = [cb];
    const s = document.createElement("script");
    s.src = src;
    s.onerror = () => fail && fail(src);
    document.head.appendChild(s);
  }
  function loadImg(src, cb, fail) {
    let im = imgs[src];
    if (!im) {
      im = imgs[src] = new Image();
      im.src = src;
    }
    if (im.complete && im.naturalWidth > 0) return cb(im);
    im.addEventListener("load", () => cb(im));
    im.addEventListener("error", () => fail && fail(src));
  }

  const srgb = (x) => (x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055);
  // Tone-mapped canvas of an HDR image at the current exposure (cached per EV).
  function toneMapped(h) {
    if (h.canvas && h.ev === st.ev) return h.canvas;
    if (!h.canvas) {
      h.canvas = document.createElement("canvas");
      h.canvas.width = h.w;
      h.canvas.height = h.h;
    }
    const ctx = h.canvas.getContext("2d");
    const img = ctx.createImageData(h.w, h.h);
    const k = Math.pow(2, st.ev);
    for (let i = 0; i < h.w * h.h; i++) {
      for (let c = 0; c < 3; c++) img.data[4 * i + c] = Math.round(255 * srgb(Math.min(1, Math.max(0, h.f[3 * i + c] * k))));
      img.data[4 * i + 3] = 255;
    }
    ctx.putImageData(img, 0, 0);
    h.ev = st.ev;
    return h.canvas;
  }

  const el = (tag, attrs, html) => {
    const e = document.createElement(tag);
    Object.entries(attrs || {}).forEach(([k, v]) => e.setAttribute(k, v));
    if (html !== undefined) e.innerHTML = html;
    return e;
  };
  const fmt = (v) => {
    if (typeof v !== "number") return String(v);
    if (Number.isInteger(v) && Math.abs(v) < 1e9) return String(v);
    const a = Math.abs(v);
    return a < 1e-3 || a >= 1e5 ? v.toExponential(2) : v.toPrecision(3);
  };
  const pct = (v) => (v >= 0 ? "+" : "") + (100 * v).toFixed(1) + " %";

  // ---- layout ----
  const root = document.getElementById("pl-viewer");
  root.innerHTML = "";
  const side = el("div", { id: "pl-side" });
  const main = el("div", { id: "pl-main" });
  root.append(side, main);
  const cellsBox = el("div", { id: "pl-cells" });
  const tbl = el("table");
  tbl.append(el("tr", {}, "<th>cell</th><th>rep</th><th>relMSE</th><th>trimmed</th><th>worst block</th>"));
  D.cells.forEach((c, i) => {
    const tr = el("tr", { "data-i": i, id: "pl-row-" + c.id });
    tr.innerHTML = `<td>${c.label}</td><td>${c.repeat}</td><td>${fmt(c.relmse)}</td>` +
      `<td>${fmt(c.relmse_trimmed)}</td><td>${pct(c.worst_block)}</td>`;
    tr.addEventListener("click", () => select(i));
    tbl.append(tr);
  });
  cellsBox.append(tbl);
  side.append(el("div", {}, "<b>Cells</b> (click, or ↑/↓)"), cellsBox, el("div", { id: "pl-metrics" }));

  const modes = [
    ["cell", "cell"], ["ref", "reference"], ["flip", "flip (F / space)"], ["slide", "slide"],
    ["relerr", "|error|"], ["signed", "signed block error"],
  ];
  const controls = el("div", { id: "pl-controls" });
  modes.forEach(([m, label]) => {
    const b = el("button", { "data-mode": m, id: "pl-mode-" + m }, label);
    b.addEventListener("click", () => setMode(m));
    controls.append(b);
  });
  const ev = el("input", { type: "range", min: "-10", max: "10", step: "0.25", value: "0", id: "pl-ev" });
  const evLabel = el("span", { id: "pl-ev-label" }, "0 EV");
  ev.addEventListener("input", () => { st.ev = parseFloat(ev.value); evLabel.textContent = st.ev + " EV"; draw(); });
  const reset = el("button", { id: "pl-reset" }, "fit (0)");
  reset.addEventListener("click", fit);
  const one = el("button", { id: "pl-one" }, "1:1");
  one.addEventListener("click", () => zoomTo(1));
  controls.append(el("br"), "exposure ", ev, " ", evLabel, " ", reset, one);
  if (D.component_name) {
    // Show the measured component (cell and reference) instead of the full image.
    const cb = el("input", { type: "checkbox", id: "pl-comp" });
    cb.addEventListener("change", () => { st.comp = cb.checked; draw(); });
    const lab = el("label", {}, " ");
    lab.append(cb, " " + D.component_name + " component");
    controls.append(lab);
  }
  const legend = el("div", { id: "pl-legend" });
  const canvas = el("canvas", { id: "pl-canvas" });
  const status = el("div", { id: "pl-status" });
  const strategiesBox = el("div", { id: "pl-strategies" });
  strategiesBox.hidden = true;
  main.append(controls, canvas, status, legend, strategiesBox);

  function cur() { return D.cells[st.cell]; }
  function refOf(c) { return D.references[c.scene] || D.references[0]; }

  // ---- drawing ----
  // The HDR images shown: the full image, or the component (when chosen and present).
  function hdrOf(x) { return st.comp && x.comp ? x.comp : x; }
  function sources(cb) {
    const c = hdrOf(cur()), r = hdrOf(refOf(cur()));
    const out = {};
    let left = 2;
    const done = () => { if (--left === 0) cb(out); };
    loadHdr(c.id, c.js, (h) => { out.cell = h; done(); }, (s) => fail("script", s));
    loadHdr(r.id, r.js, (h) => { out.ref = h; done(); }, (s) => fail("script", s));
  }
  function fail(kind, src) {
    status.textContent = "could not load " + kind + " " + src;
    if (selftest) {
      selftest.failed.push(src);
      if (selftest.next) setTimeout(selftest.next, 0);
    }
  }

  function fit() {
    const c = hdrOf(cur()), r = hdrOf(refOf(cur()));
    const h = hdrs[c.id] || hdrs[r.id];
    const W = canvas.width, H = canvas.height;
    const w = h ? h.w : 256, hh = h ? h.h : 256;
    st.scale = Math.max(1, Math.floor(Math.min(W / w, H / hh))) || Math.min(W / w, H / hh);
    if (w * st.scale > W || hh * st.scale > H) st.scale = Math.min(W / w, H / hh);
    st.ox = Math.round((W - w * st.scale) / 2);
    st.oy = Math.round((H - hh * st.scale) / 2);
    draw();
  }
  function zoomTo(s, cx, cy) {
    cx = cx === undefined ? canvas.width / 2 : cx;
    cy = cy === undefined ? canvas.height / 2 : cy;
    const ix = (cx - st.ox) / st.scale, iy = (cy - st.oy) / st.scale;
    st.scale = Math.min(256, Math.max(0.05, s));
    st.ox = cx - ix * st.scale;
    st.oy = cy - iy * st.scale;
    draw();
  }

  let pending = 0;
  function draw() {
    const token = ++pending;
    const c = cur();
    sources((src) => {
      if (token !== pending) return;
      const finish = (extra) => {
        paint(src, extra);
        canvas.setAttribute("data-shown", c.id + ":" + st.mode + (st.comp && c.comp ? ":comp" : ""));
        if (selftest && selftest.onDrawn) selftest.onDrawn();
      };
      if (st.mode === "relerr" || st.mode === "signed") {
        loadImg(st.mode === "relerr" ? c.relerr : c.signed, (im) => token === pending && finish(im), (s) => fail("image", s));
      } else finish(null);
    });
  }

  function paint(src, errImg) {
    const ctx = canvas.getContext("2d");
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#111";
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    ctx.imageSmoothingEnabled = false;
    const w = src.cell.w, h = src.cell.h;
    const put = (img) => ctx.drawImage(img, st.ox, st.oy, w * st.scale, h * st.scale);
    const mode = st.mode;
    if (errImg) put(errImg);
    else if (mode === "cell" || (mode === "flip" && !st.showRef)) put(toneMapped(src.cell));
    else if (mode === "ref" || mode === "flip") put(toneMapped(src.ref));
    else if (mode === "slide") {
      const x = Math.round(st.split * canvas.width);
      ctx.save();
      ctx.beginPath();
      ctx.rect(0, 0, x, canvas.height);
      ctx.clip();
      put(toneMapped(src.cell));
      ctx.restore();
      ctx.save();
      ctx.beginPath();
      ctx.rect(x, 0, canvas.width - x, canvas.height);
      ctx.clip();
      put(toneMapped(src.ref));
      ctx.restore();
      ctx.fillStyle = "#ff0";
      ctx.fillRect(x, 0, 1, canvas.height);
      ctx.font = "13px sans-serif";
      ctx.fillText("cell", x - 34, 16);
      ctx.fillText("reference", x + 6, 16);
    }
    if (mode === "signed") {
      // Outline the worst measured block.
      const b = D.block * st.scale;
      ctx.strokeStyle = "#ff0";
      ctx.lineWidth = 2;
      ctx.strokeRect(st.ox + c0(0) * st.scale, st.oy + c0(1) * st.scale, b, b);
      ctx.fillStyle = "#ff0";
      ctx.font = "12px sans-serif";
      ctx.fillText("worst " + pct(cur().worst_block), st.ox + c0(0) * st.scale, st.oy + c0(1) * st.scale - 4);
    }
    const what = st.comp && cur().comp && !errImg ? D.component_name + " " : "";
    const showing = what + (errImg ? (mode === "relerr" ? "|error|" : "signed block error")
      : mode === "slide" ? "cell | reference"
      : (mode === "ref" || (mode === "flip" && st.showRef)) ? "reference" : "cell");
    ctx.font = "bold 14px sans-serif";
    ctx.fillStyle = "#fff";
    ctx.fillText(showing + "  ·  " + cur().label + " r" + cur().repeat + "  ·  ×" + fmt(st.scale), 8, canvas.height - 10);
    updateStatus();
  }

  function c0(k) { return cur().worst_block_at[k]; }

  function updateStatus() {
    const c = hdrOf(cur()), r = hdrOf(refOf(cur()));
    let s = "";
    if (st.mouse) {
      const x = Math.floor((st.mouse[0] - st.ox) / st.scale), y = Math.floor((st.mouse[1] - st.oy) / st.scale);
      const hc = hdrs[c.id], hr = hdrs[r.id];
      if (hc && x >= 0 && y >= 0 && x < hc.w && y < hc.h) {
        const i = 3 * (y * hc.w + x);
        const rgb = (h) => h ? [0, 1, 2].map((k) => fmt(h.f[i + k])).join(" ") : "?";
        s = `pixel (${x}, ${y})   cell ${rgb(hc)}   reference ${rgb(hr)}`;
      }
    }
    status.textContent = s + "\ndrag: pan · wheel: zoom (nearest neighbour) · F/space: flip · ↑/↓: cell";
  }

  function showMetrics() {
    const c = cur(), r = refOf(c);
    const m = c.metrics.map(([k, v]) => {
      const val = k === "worst block" ? pct(v) : k === "worst pixel share" ? (100 * v).toFixed(1) + " %" : Array.isArray(v) ? "(" + v.join(", ") + ")" : fmt(v);
      return `<tr><td>${k}</td><td>${val}</td></tr>`;
    }).join("");
    const noise = r.noise_relmse == null ? "unknown" : fmt(r.noise_relmse);
    const k = c.component;
    const comp = k ? `<tr><th colspan="2">${k.name} component</th></tr><tr><td>relMSE</td><td>${fmt(k.relmse)}</td></tr>` +
      `<tr><td>relMSE trimmed</td><td>${fmt(k.robust.relmse_trimmed)}</td></tr><tr><td>SMAPE</td><td>${fmt(k.robust.smape)}</td></tr>` +
      `<tr><td>worst block</td><td>${pct(k.robust.worst_block)}</td></tr>` +
      `<tr><td>reference noise</td><td>${r.component_noise_relmse == null ? "unknown" : fmt(r.component_noise_relmse)}</td></tr>` : "";
    document.getElementById("pl-metrics").innerHTML =
      `<p><b>${c.label}</b>, repeat ${c.repeat}<br><code>${c.id}</code></p><table>${m}` +
      `<tr><td>reference noise (relMSE)</td><td>${noise}</td></tr>${comp}</table>` +
      `<p><a href="${c.png}">PNG</a> · <a href="${c.relerr}">|error|</a> · <a href="${c.signed}">signed</a> · <a href="${r.png}">reference</a></p>`;
    showStrategies(c);
  }

  // Per-strategy images of bidirectional cells: one row per (s, t) technique, its
  // weighted contribution (what it adds to the image) beside the technique alone
  // (unweighted), then vcm's merging part. PNGs, each a link to itself.
  function showStrategies(c) {
    const box = document.getElementById("pl-strategies");
    const list = c.strategies || [];
    box.hidden = list.length === 0;
    if (list.length === 0) { box.innerHTML = ""; return; }
    const byName = {};
    list.forEach((x) => { byName[x.name] = x; });
    const img = (x) => x ? `<a href="${x.png}"><img class="pl-strategy" src="${x.png}" alt="${x.name}" title="${x.name}" data-name="${x.name}"></a>` : "";
    const rows = list.filter((x) => /^s\d+-t\d+$/.test(x.name)).map((x) => {
      const [s, t] = x.name.slice(1).split("-t").map(Number);
      return { s, t, name: x.name };
    }).sort((a, b) => (a.s + a.t) - (b.s + b.t) || a.s - b.s);
    let html = `<h3>Strategies of <code>${c.id}</code></h3><p>s light vertices, t camera vertices (path length s + t − 1 edges); ` +
      `weighted: the technique's share of the image; unweighted: the technique alone (a full estimate of that path length).</p>` +
      `<table><tr><th>technique</th><th>weighted</th><th>unweighted</th></tr>`;
    rows.forEach((r) => {
      html += `<tr data-strategy="${r.name}"><td>s = ${r.s}, t = ${r.t}</td><td>${img(byName[r.name])}</td><td>${img(byName[r.name + "-unweighted"])}</td></tr>`;
    });
    if (byName.merge) html += `<tr data-strategy="merge"><td>merging</td><td>${img(byName.merge)}</td><td></td></tr>`;
    box.innerHTML = html + "</table>";
  }

  function setLegend() {
    if (st.mode === "signed") {
      legend.innerHTML = `signed relative error of each ${D.block}-px block mean: <span class="legend" style="background:linear-gradient(90deg,#3b4cc0,#dddddd,#b40426)"></span> ` +
        `−${100 * D.signed_range} % (too dark) … +${100 * D.signed_range} % (too bright); dark grey: reference black`;
    } else if (st.mode === "relerr") {
      legend.innerHTML = `per-pixel relative error √((x−ref)²/(ref²+0.01)): <span class="legend" style="background:linear-gradient(90deg,#000005,#540f6e,#ba3654,#fa8c0a,#fcffa3)"></span> ` +
        `${D.relerr_range[0]} … ${D.relerr_range[1]} (log)`;
    } else legend.textContent = "exposure applies to the linear radiance (sRGB display)";
  }

  function setMode(m) {
    st.mode = m;
    document.querySelectorAll("#pl-controls button[data-mode]").forEach((b) => b.classList.toggle("on", b.dataset.mode === m));
    setLegend();
    draw();
  }

  function select(i) {
    const firstFit = !hdrs[D.cells[i].id] && st.scale === 1 && st.ox === 0;
    st.cell = (i + D.cells.length) % D.cells.length;
    document.querySelectorAll("#pl-cells tr.sel").forEach((t) => t.classList.remove("sel"));
    const row = document.getElementById("pl-row-" + cur().id);
    if (row) { row.classList.add("sel"); row.scrollIntoView({ block: "nearest" }); }
    showMetrics();
    draw();
    if (firstFit) sources(() => fit());
  }

  // ---- interaction ----
  function resize() {
    const r = canvas.getBoundingClientRect();
    canvas.width = Math.max(200, Math.round(r.width));
    canvas.height = Math.max(200, Math.round(r.height));
  }
  let drag = null;
  const pos = (e) => {
    const r = canvas.getBoundingClientRect();
    return [(e.clientX - r.left) * canvas.width / r.width, (e.clientY - r.top) * canvas.height / r.height];
  };
  canvas.addEventListener("mousedown", (e) => { drag = pos(e); });
  window.addEventListener("mouseup", () => { drag = null; });
  canvas.addEventListener("mousemove", (e) => {
    const p = pos(e);
    st.mouse = p;
    if (drag) { st.ox += p[0] - drag[0]; st.oy += p[1] - drag[1]; drag = p; draw(); }
    else if (st.mode === "slide") { st.split = p[0] / canvas.width; draw(); }
    else updateStatus();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const p = pos(e);
    zoomTo(st.scale * (e.deltaY < 0 ? 2 : 0.5), p[0], p[1]);
  }, { passive: false });
  window.addEventListener("keydown", (e) => {
    if (e.target && e.target.tagName === "INPUT") return;
    if (e.key === "f" || e.key === "F" || e.key === " ") { e.preventDefault(); if (st.mode !== "flip") setMode("flip"); st.showRef = !st.showRef; draw(); }
    else if (e.key === "ArrowDown") { e.preventDefault(); select(st.cell + 1); }
    else if (e.key === "ArrowUp") { e.preventDefault(); select(st.cell - 1); }
    else if (e.key === "0") fit();
  });

  // ---- start: options from the hash ----
  const opts = {};
  location.hash.replace(/^#/, "").split("&").filter(Boolean).forEach((kv) => {
    const [k, v] = kv.split("=");
    opts[decodeURIComponent(k)] = v === undefined ? true : decodeURIComponent(v);
  });
  let selftest = opts.selftest ? { failed: [], checked: [], comp_checked: [] } : null;
  resize();
  if (opts.comp && D.component_name) {
    st.comp = true;
    document.getElementById("pl-comp").checked = true;
  }
  if (opts.ev) { st.ev = parseFloat(opts.ev) || 0; ev.value = st.ev; evLabel.textContent = st.ev + " EV"; }
  st.mode = modes.some(([m]) => m === opts.mode) ? opts.mode : "flip";
  const start = Math.max(0, D.cells.findIndex((c) => c.id === opts.cell));
  if (D.cells.length === 0) {
    root.textContent = "No cells.";
  } else {
    setMode(st.mode);
    select(start);
  }

  // ---- self-test (used by the browser test): every <img> loads, every cell draws ----
  if (selftest && D.cells.length) {
    const out = document.getElementById("selftest-result");
    const finish = () => {
      const pageImgs = Array.from(document.images);
      const bad = pageImgs.filter((im) => !(im.complete && im.naturalWidth > 0)).map((im) => im.getAttribute("src"));
      // Back to the cell and mode the hash asked for, as a user would see it.
      st.mode = modes.some(([m]) => m === opts.mode) ? opts.mode : "flip";
      st.comp = false;
      setMode(st.mode);
      select(start);
      const sel = document.querySelector("#pl-cells tr.sel");
      const strat = Array.from(document.querySelectorAll("#pl-strategies img"));
      const res = {
        done: true, page_images: pageImgs.length, page_images_failed: bad, cells: D.cells.length,
        cells_checked: selftest.checked, comp_checked: selftest.comp_checked, failed: selftest.failed,
        selected: sel ? sel.id.replace(/^pl-row-/, "") : null, mode: st.mode,
        strategies_shown: strat.map((im) => im.dataset.name),
      };
      // The selected cell's strategy images, once they have loaded.
      whenImagesLoaded(() => {
        res.strategies_failed = strat.filter((im) => !(im.complete && im.naturalWidth > 0)).map((im) => im.getAttribute("src"));
        out.textContent = JSON.stringify(res);
        out.hidden = false;
        const ok = bad.length === 0 && selftest.failed.length === 0 && res.strategies_failed.length === 0;
        document.body.setAttribute("data-selftest", ok ? "pass" : "fail");
      });
    };
    const whenImagesLoaded = (cb) => {
      const pending = Array.from(document.images).filter((im) => !im.complete);
      let left = pending.length;
      if (left === 0) return cb();
      pending.forEach((im) => {
        const d = () => { if (--left === 0) cb(); };
        im.addEventListener("load", d);
        im.addEventListener("error", d);
      });
    };
    // Every cell, each in the three modes that load different files.
    const steps = [];
    D.cells.forEach((c, i) => ["cell", "relerr", "signed"].concat(c.comp ? ["comp"] : []).forEach((m) => steps.push([i, m])));
    let k = 0;
    const next = () => {
      selftest.next = next;
      if (k === steps.length) { selftest.onDrawn = null; return whenImagesLoaded(finish); }
      const [i, m] = steps[k++];
      const want = D.cells[i].id + ":" + (m === "comp" ? "slide:comp" : m);
      selftest.onDrawn = () => {
        if (canvas.getAttribute("data-shown") === want) {
          selftest.onDrawn = null;
          if (m === "signed") selftest.checked.push(D.cells[i].id);
          if (m === "comp") selftest.comp_checked.push(D.cells[i].id);
          setTimeout(next, 0);
        }
      };
      st.comp = m === "comp";
      st.mode = m === "comp" ? "slide" : m;
      select(i);
    };
    next();
  }
})();
