/* lsadphoto luminance viewer (package file lsadphoto/viewer/viewer.js).
 *
 * Decodes the arrays that lsadphoto.viewer.page embeds (byte planes, byte differences,
 * zlib; see that module), draws them on canvases and sums them. Browser APIs only:
 * canvas 2D, DecompressionStream, Blob; no library, no network.
 *
 * Conventions: pixel (row, col) has its centre at image coordinates (u = col, v = row) and
 * covers ±½ px around it (lsadphoto.geometry.base). Luminance in cd/m², angles in degrees
 * on the page, solid angles in sr. Every value shown comes from the embedded float32
 * arrays at full resolution; the display alone samples them at the screen's resolution.
 *
 * Loading: a large map's page holds a display preview (block means) before its other arrays
 * and calls lsadViewerStart right after it, so the preview is drawn, zoomed and panned while
 * the browser still parses the rest; the full-resolution arrays are decoded once the page is
 * parsed (promise `ready`). Until then the probe, the points, the regions and the CSV wait:
 * valueAt and the other readers throw rather than answer from the preview.
 */
(function () {
  "use strict";

  const viewers = [];
  window.lsadViewers = viewers;

  // ------------------------------------------------------------------ decoding

  let halfTable = null;
  function halfToFloat() {
    if (halfTable) return halfTable;
    halfTable = new Float32Array(65536);
    for (let h = 0; h < 65536; h++) {
      const s = h & 0x8000 ? -1 : 1, e = (h >> 10) & 0x1f, f = h & 0x3ff;
      halfTable[h] = e === 0 ? s * f * Math.pow(2, -24)
        : e === 31 ? (f ? NaN : s * Infinity) : s * (1 + f / 1024) * Math.pow(2, e - 15);
    }
    return halfTable;
  }

  const ITEM_SIZE = { float32: 4, float16: 2, uint8: 1, uint16: 2, uint32: 4 };

  /** The bytes of one embedded part (base64 → zlib → byte differences and planes undone;
   * `k` bytes per element). Runs in a decoding Worker, whose source is this function's
   * text, or here where a page cannot start Workers. base64 is read by the browser's own
   * decoder (Uint8Array.fromBase64), else by fetch of a data: URL (no network either way). */
  async function decodePart(text, k) {
    const raw = typeof Uint8Array.fromBase64 === "function" ? new Blob([Uint8Array.fromBase64(text)])
      : await (await fetch("data:application/octet-stream;base64," + text)).blob();
    const stream = raw.stream().pipeThrough(new DecompressionStream("deflate"));
    const planes = new Uint8Array(await new Response(stream).arrayBuffer());
    // Undo the byte differences (a running sum mod 256) and the byte planes in one pass.
    const n = planes.length / k;
    const bytes = k > 1 ? new Uint8Array(planes.length) : planes;
    let sum = 0;
    for (let p = 0; p < k; p++) {
      const offset = p * n;
      for (let i = 0, j = p; i < n; i++, j += k) {
        sum = (sum + planes[offset + i]) & 0xff;
        bytes[j] = sum;
      }
    }
    return bytes;
  }

  const WORKER_SOURCE = "const decodePart = " + decodePart.toString() + ";\n" +
    "onmessage = async (event) => { const job = event.data; try { const bytes = await decodePart(job.text, job.k);" +
    " postMessage({ id: job.id, bytes: bytes }, [bytes.buffer]); } catch (error) {" +
    " postMessage({ id: job.id, error: String((error && error.message) || error) }); } };";

  /** Decoding Workers (one per core, at most 4) built from a Blob URL, and their queue. Parts
   * go to the first idle Worker in the order asked for; where Workers cannot start (or one
   * fails to load) the parts are decoded on the page's own thread. */
  const pool = { workers: null, queue: [], next: 0 };
  function startWorkers() {
    pool.workers = [];
    let url;
    try {
      url = URL.createObjectURL(new Blob([WORKER_SOURCE], { type: "text/javascript" }));
    } catch (error) { return; }
    const count = Math.max(1, Math.min(4, navigator.hardwareConcurrency || 2));
    for (let n = 0; n < count; n++) {
      let worker;
      try { worker = new Worker(url); } catch (error) { break; }
      const slot = { worker: worker, job: null };
      worker.onmessage = (event) => {
        const job = slot.job; slot.job = null;
        if (event.data.error) job.reject(new Error(event.data.error)); else job.resolve(event.data.bytes);
        dispatch();
      };
      worker.onerror = (event) => {
        event.preventDefault();
        pool.workers = pool.workers.filter((s) => s !== slot);
        if (slot.job) pool.queue.unshift(slot.job);
        slot.job = null;
        dispatch();
      };
      pool.workers.push(slot);
    }
  }
  function dispatch() {
    if (!pool.workers.length) {
      for (const job of pool.queue.splice(0)) decodePart(job.text, job.k).then(job.resolve, job.reject);
      return;
    }
    for (const slot of pool.workers) {
      if (slot.job || !pool.queue.length) continue;
      slot.job = pool.queue.shift();
      slot.worker.postMessage({ id: pool.next++, text: slot.job.text, k: slot.job.k });
    }
  }
  function decodeBytes(text, k) {
    if (!pool.workers) startWorkers();
    return new Promise((resolve, reject) => {
      pool.queue.push({ text: text, k: k, resolve: resolve, reject: reject });
      dispatch();
    });
  }

  /** An embedded array (its parts decoded in parallel and joined) as a typed array. */
  async function decodeArray(container, desc) {
    const elements = container.querySelectorAll('script[data-array="' + desc.name + '"]');
    if (!elements.length || elements.length !== (desc.parts || 1)) throw new Error("missing embedded array " + desc.name);
    const k = ITEM_SIZE[desc.dtype];
    const parts = await Promise.all(Array.from(elements, (element) => decodeBytes(element.textContent, k)));
    let bytes = parts[0];
    if (parts.length > 1) {
      bytes = new Uint8Array(parts.reduce((total, part) => total + part.length, 0));
      let offset = 0;
      for (const part of parts) { bytes.set(part, offset); offset += part.length; }
    }
    const buffer = bytes.buffer;
    switch (desc.dtype) {
      case "float32": return new Float32Array(buffer);
      case "float16": return new Uint16Array(buffer); // read through halfToFloat()
      case "uint8": return bytes;
      case "uint16": return new Uint16Array(buffer);
      case "uint32": return new Uint32Array(buffer);
      default: throw new Error("unknown dtype " + desc.dtype);
    }
  }

  function colourTable(base64) {
    const text = atob(base64);
    const out = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) out[i] = text.charCodeAt(i);
    return out;
  }

  // ------------------------------------------------------------------ formatting

  function fmt(value, digits) {
    if (value === null || value === undefined || !Number.isFinite(value)) return "—";
    const d = digits || 4;
    if (value !== 0 && (Math.abs(value) >= 1e6 || Math.abs(value) < 1e-3)) return value.toExponential(d - 1);
    return Number(value.toPrecision(d)).toString();
  }
  function deg(rad) { return rad * 180 / Math.PI; }
  function el(tag, attrs, text) {
    const node = document.createElement(tag);
    if (attrs) for (const [k, v] of Object.entries(attrs)) {
      if (k === "class") node.className = v; else node.setAttribute(k, v);
    }
    if (text !== undefined) node.textContent = text;
    return node;
  }
  function csvField(value) {
    if (value === null || value === undefined) return "";
    if (typeof value === "number") return Number.isFinite(value) ? String(value) : "";
    const s = String(value);
    return /[",\n]/.test(s) ? '"' + s.replace(/"/g, '""') + '"' : s;
  }

  // ------------------------------------------------------------------ the viewer

  class Viewer {
    constructor(container) {
      this.container = container;
      this.meta = JSON.parse(container.querySelector("script[data-meta]").textContent);
      this.isReady = false; // the full-resolution data are decoded
      this.state = "loading"; // then "preview" (where the page has one), "full" or "failed"
      this.display = null; // what the panels draw: per map { L, block [px], cols }
      this.timings = {}; // performance.now() [ms] of the frames: preview, full
      this.regions = [];
      this.points = [];
      this.probe = null;
      this.draft = null; // region being drawn
      this.tool = "probe";
      this.mode = "false";
      this.colourMap = this.meta.colour_maps[0];
      this.layout = this.meta.maps.length > 1 ? "side" : "single";
      this.showSources = true;
      this.showBand = true;
      this.showZones = true;
      this.exposure = 0;
      this.tables = {};
      for (const [k, v] of Object.entries(this.meta.colour_tables)) this.tables[k] = colourTable(v);
      const first = this.meta.maps[0];
      this.rows = first.rows;
      this.cols = first.cols;
      this.range = first.range.slice();
      this.ready = new Promise((resolve, reject) => { this._resolve = resolve; this._reject = reject; });
      this.previewReady = new Promise((resolve, reject) => { this._shown = resolve; this._notShown = reject; });
      this.buildDom();
    }

    // --- data ---

    async load() {
      try {
        const previews = this.meta.maps.map((m) => m.preview);
        if (previews.every(Boolean)) {
          const arrays = await Promise.all(previews.map((p) => decodeArray(this.container, p)));
          this.display = arrays.map((L, k) => ({ L: L, block: previews[k].block,
            cols: Math.ceil(this.cols / previews[k].block) }));
          this.state = "preview";
          this.status.textContent = "preview (blocks of " + previews[0].block + " × " + previews[0].block +
            " px): loading the full-resolution data…";
          this.fit();
          this.shown("preview");
        }
        await documentParsed();
        // A test hook: a promise set before the page loads holds the full-resolution decoding.
        if (window.lsadViewerHoldFullResolution) await window.lsadViewerHoldFullResolution;
        const t0 = performance.now();
        // Every array's parts are asked for at once (luminance first): the Workers decode
        // them in parallel while this thread waits.
        const decode = (desc) => (desc ? decodeArray(this.container, desc) : Promise.resolve(null));
        const maps = Promise.all(this.meta.maps.map(async (m) => {
          const score = m.score || {};
          const [L, U, labels, band, zones] = await Promise.all([decode(m.luminance), decode(m.uncertainty),
            decode(score.labels), decode(score.band), decode(score.zones)]);
          // The Q contrast map is decoded when first shown (loadContrast).
          return { meta: m, L: L, U: U, labels: labels, contrast: null, band: band, zones: zones };
        }));
        const g = this.meta.geometry;
        const geometry = g ? (async () => {
          const keys = Object.keys(g.fields);
          const [valid, exactIndex, fields, exact] = await Promise.all([decode(g.valid), decode(g.exact_index),
            Promise.all(keys.map((key) => decode(g.fields[key]))), Promise.all(keys.map((key) => decode(g.exact[key])))]);
          const out = { meta: g, fields: {}, exact: {}, valid: valid, exactIndex: exactIndex,
            nodeRows: g.node_rows, nodeCols: g.node_cols };
          keys.forEach((key, n) => { out.fields[key] = fields[n]; out.exact[key] = exact[n]; });
          return out;
        })() : Promise.resolve(undefined);
        [this.maps, this.geometry] = await Promise.all([maps, geometry]);
        this.decodeMs = performance.now() - t0;
        // Workers that decoded the data (0: decoded on the page's own thread).
        this.decodeWorkers = pool.workers.length;
        this.isReady = true;
        this.state = "full";
        this.status.textContent = "";
        const first = !this.display;
        this.display = this.maps.map((m) => ({ L: m.L, block: 1, cols: this.cols }));
        // Over a preview the user's zoom and pan stay.
        if (first) this.fit(); else this.render();
        this.updateTables();
        if (this.probe) this.setProbe(this.probe.row, this.probe.col);
        this.shown("full");
        this._resolve(this);
      } catch (error) {
        this.state = "failed";
        this.status.textContent = "the viewer could not decode its data: " + error.message;
        console.error(error);
        this._notShown(error);
        this._reject(error);
      }
    }

    /** Note a first frame of `kind` ("preview", "full"): `previewReady` resolves at the
     * first; `timings[kind]` is the time [ms, performance.now()] of the animation frame. */
    shown(kind) {
      this._shown(this);
      requestAnimationFrame(() => { this.timings[kind] = performance.now(); });
    }

    /** The decoded full-resolution maps; an Error until `ready` has resolved, so that no
     * value is ever read from the preview. */
    full() {
      if (!this.isReady) throw new Error("lsadViewer: the full-resolution data are still loading (await lsadViewer.ready)");
      return this.maps;
    }

    /** Decode the Q contrast maps (an overlay: left out of the first load). */
    async loadContrast() {
      await this.ready;
      for (const m of this.maps) {
        const score = m.meta.score;
        if (score && score.contrast && !m.contrast) m.contrast = await decodeArray(this.container, score.contrast);
      }
    }

    index(row, col) {
      if (!(row >= 0 && row < this.rows && col >= 0 && col < this.cols)) return -1;
      return (row | 0) * this.cols + (col | 0);
    }

    /** Luminance [cd/m²] of pixel (row, col) of map `which` (0 or 1); NaN where unknown. */
    valueAt(row, col, which) {
      const m = this.full()[which || 0], i = this.index(row, col);
      return i < 0 ? NaN : m.L[i];
    }

    /** Standard uncertainty [cd/m²] of that value: the map's own, else its calibration's. */
    uncertaintyAt(row, col, which) {
      const m = this.full()[which || 0], i = this.index(row, col);
      if (i < 0) return NaN;
      if (m.U) return m.U[i];
      const u = m.meta.calibration_uncertainty;
      return u > 0 ? m.L[i] * u : NaN;
    }

    /** Geometry of pixel (row, col): direction (camera frame), solid angle [sr], position
     * index interpolated bilinearly from the embedded grid (exact values at the rim of the
     * image circle); σ, τ [rad] and cos σ of that direction in the observer frame (as
     * lsadphoto.geometry.ObserverFrame.angles). null where the pixel has no geometry. */
    geometryAt(row, col) {
      this.full();
      const g = this.geometry, i = this.index(row, col);
      if (!g || i < 0 || !g.valid[i]) return null;
      const F = g.fields;
      let dx, dy, dz, omega, p;
      const k = this.exactSlot(i);
      if (k >= 0) {
        const E = g.exact;
        dx = E.dx[k]; dy = E.dy[k]; dz = E.dz[k]; omega = E.solid_angle[k]; p = E.position_index[k];
      } else {
        const nr = g.nodeRows, nc = g.nodeCols, stride = g.meta.stride;
        const a = Math.min(Math.floor(row / stride), Math.max(nr.length - 2, 0));
        const b = Math.min(Math.floor(col / stride), Math.max(nc.length - 2, 0));
        const a1 = Math.min(a + 1, nr.length - 1), b1 = Math.min(b + 1, nc.length - 1);
        const ta = a1 > a ? (row - nr[a]) / (nr[a1] - nr[a]) : 0;
        const tb = b1 > b ? (col - nc[b]) / (nc[b1] - nc[b]) : 0;
        const w = nc.length;
        const at = (f) => {
          const top = f[a * w + b] * (1 - tb) + f[a * w + b1] * tb;
          const bottom = f[a1 * w + b] * (1 - tb) + f[a1 * w + b1] * tb;
          return top * (1 - ta) + bottom * ta;
        };
        dx = at(F.dx); dy = at(F.dy); dz = at(F.dz); omega = at(F.solid_angle); p = at(F.position_index);
      }
      const norm = Math.hypot(dx, dy, dz);
      dx /= norm; dy /= norm; dz /= norm;
      const [v, u, h] = g.meta.axes;
      const forward = dx * v[0] + dy * v[1] + dz * v[2];
      const up = dx * u[0] + dy * u[1] + dz * u[2];
      const side = dx * h[0] + dy * h[1] + dz * h[2];
      const lateral = Math.hypot(up, side);
      const sigma = Math.atan2(lateral, forward);
      const tau = lateral < g.meta.on_axis ? 0 : Math.atan2(Math.abs(side), up);
      return { direction: [dx, dy, dz], solidAngle: omega, sigma: sigma, tau: tau,
        positionIndex: p, cosSigma: Math.cos(sigma) };
    }

    /** Position of flat pixel index i in the list of exactly embedded pixels, or −1. */
    exactSlot(i) {
      const list = this.geometry.exactIndex;
      let lo = 0, hi = list.length - 1;
      while (lo <= hi) {
        const mid = (lo + hi) >> 1, value = list[mid];
        if (value === i) return mid;
        if (value < i) lo = mid + 1; else hi = mid - 1;
      }
      return -1;
    }

    sourceLabelAt(row, col, which) {
      const m = this.full()[which || 0], i = this.index(row, col);
      return i < 0 || !m.labels ? 0 : m.labels[i];
    }

    /** 1 where pixel (row, col) is in evalglare's band of the score (-B), else 0. */
    bandAt(row, col, which) {
      const m = this.full()[which || 0], i = this.index(row, col);
      return i < 0 || !m.band ? 0 : m.band[i];
    }

    /** Zone (1, 2; 0 outside) of pixel (row, col) in the score's evalglare zones (-l/-L). */
    zoneAt(row, col, which) {
      const m = this.full()[which || 0], i = this.index(row, col);
      return i < 0 || !m.zones ? 0 : m.zones[i];
    }

    contrastAt(row, col, which) {
      const m = this.full()[which || 0], i = this.index(row, col);
      return i < 0 || !m.contrast ? NaN : halfToFloat()[m.contrast[i]];
    }

    sources(which) {
      const score = this.meta.maps[which || 0].score;
      return score ? score.sources : [];
    }

    /** Statistics of the pixels whose centres `inside(row, col)` within the bounding box. */
    regionStatsBox(box, inside, which) {
      const m = this.full()[which || 0];
      const r0 = Math.max(0, Math.ceil(box[0])), r1 = Math.min(this.rows - 1, Math.floor(box[1]));
      const c0 = Math.max(0, Math.ceil(box[2])), c1 = Math.min(this.cols - 1, Math.floor(box[3]));
      const values = [], weights = [];
      let sumW = 0, sumLW = 0, sumE = 0, max = -Infinity, n = 0;
      const geometric = !!this.geometry;
      for (let r = r0; r <= r1; r++) {
        for (let c = c0; c <= c1; c++) {
          if (!inside(r, c)) continue;
          const L = m.L[r * this.cols + c];
          if (!Number.isFinite(L)) continue;
          let w = 1, cos = 0;
          if (geometric) {
            const g = this.geometryAt(r, c);
            if (!g) continue;
            w = g.solidAngle; cos = g.cosSigma;
          }
          n++; sumW += w; sumLW += L * w; if (cos > 0) sumE += L * w * cos;
          if (L > max) max = L;
          values.push(L); weights.push(w);
        }
      }
      if (n === 0) return { n: 0, solidAngle: 0, mean: NaN, median: NaN, max: NaN, illuminance: NaN };
      const order = values.map((_, k) => k).sort((p, q) => values[p] - values[q]);
      let cumulative = 0, median = values[order[order.length - 1]];
      for (const k of order) {
        cumulative += weights[k];
        if (cumulative >= sumW / 2) { median = values[k]; break; }
      }
      return { n: n, solidAngle: geometric ? sumW : NaN, mean: sumLW / sumW, median: median,
        max: max, illuminance: geometric ? sumE : NaN };
    }

    /** Statistics of a region of map `which` (cached on the region: the maps never change). */
    regionStats(region, which) {
      const k = which || 0;
      region.cache = region.cache || {};
      if (!(k in region.cache)) region.cache[k] = this.computeRegionStats(region, k);
      return region.cache[k];
    }

    computeRegionStats(region, which) {
      if (region.shape === "circle") {
        const [row, col, radius] = [region.row, region.col, region.radius];
        const r2 = radius * radius;
        return this.regionStatsBox([row - radius, row + radius, col - radius, col + radius],
          (r, c) => (r - row) * (r - row) + (c - col) * (c - col) <= r2, which);
      }
      const pts = region.points;
      const rs = pts.map((p) => p[0]), cs = pts.map((p) => p[1]);
      const inside = (r, c) => {
        let hit = false;
        for (let i = 0, j = pts.length - 1; i < pts.length; j = i++) {
          const [ri, ci] = pts[i], [rj, cj] = pts[j];
          if ((ri > r) !== (rj > r) && c < (cj - ci) * (r - ri) / (rj - ri) + ci) hit = !hit;
        }
        return hit;
      };
      return this.regionStatsBox([Math.min(...rs), Math.max(...rs), Math.min(...cs), Math.max(...cs)],
        inside, which);
    }

    /** ω-weighted mean luminance [cd/m²] of the pixels whose centres lie within radius_px
     * of (row, col) (the plain mean where the map has no geometry). */
    regionMean(row, col, radius, which) {
      return this.regionStats({ shape: "circle", row: row, col: col, radius: radius }, which).mean;
    }

    addCircle(row, col, radius) {
      this.regions.push({ id: this.regions.length + 1, shape: "circle", row: row, col: col, radius: radius });
      this.updateTables(); this.drawOverlay();
    }
    addPolygon(points) {
      this.regions.push({ id: this.regions.length + 1, shape: "polygon", points: points.map((p) => [p[0], p[1]]) });
      this.updateTables(); this.drawOverlay();
    }
    pin(row, col) {
      this.points.push({ id: this.points.length + 1, row: row | 0, col: col | 0 });
      this.updateTables(); this.drawOverlay();
    }

    pointRecord(p, which) {
      const g = this.geometryAt(p.row, p.col);
      return { L: this.valueAt(p.row, p.col, which), U: this.uncertaintyAt(p.row, p.col, which), g: g };
    }

    /** CSV of the pinned points and the regions (one row per map). */
    csv() {
      const header = ["kind", "id", "map", "shape", "row", "col", "radius_px", "vertices_row_col",
        "n_pixels", "solid_angle_sr", "luminance_cd_m2", "uncertainty_cd_m2", "mean_cd_m2",
        "median_cd_m2", "max_cd_m2", "illuminance_lx", "sigma_deg", "tau_deg", "position_index",
        "pixel_solid_angle_sr"];
      const lines = [header.join(",")];
      this.full().forEach((m, k) => {
        for (const p of this.points) {
          const q = this.pointRecord(p, k);
          lines.push([ "point", p.id, m.meta.name, "", p.row, p.col, "", "", 1, "", q.L, q.U, "", "", "", "",
            q.g ? deg(q.g.sigma) : null, q.g ? deg(q.g.tau) : null, q.g ? q.g.positionIndex : null,
            q.g ? q.g.solidAngle : null].map(csvField).join(","));
        }
        for (const r of this.regions) {
          const s = this.regionStats(r, k);
          const vertices = r.shape === "polygon" ? r.points.map((p) => p[0] + " " + p[1]).join(";") : "";
          lines.push(["region", r.id, m.meta.name, r.shape, r.shape === "circle" ? r.row : "",
            r.shape === "circle" ? r.col : "", r.shape === "circle" ? r.radius : "", vertices, s.n,
            s.solidAngle, "", "", s.mean, s.median, s.max, s.illuminance, "", "", "", ""].map(csvField).join(","));
        }
      });
      return lines.join("\n") + "\n";
    }

    // --- DOM ---

    buildDom() {
      const c = this.container, meta = this.meta;
      const head = el("div", { class: "lv-head" });
      head.appendChild(el("h3", null, meta.title));
      this.status = el("span", { class: "lv-status" }, "decoding the map…");
      head.appendChild(this.status);
      c.appendChild(head);

      const controls = el("div", { class: "lv-controls" });
      const select = (label, options, value, onchange) => {
        const wrap = el("label", null, label + " ");
        const s = el("select");
        for (const [v, text] of options) {
          const o = el("option", { value: v }, text);
          if (v === value) o.selected = true;
          s.appendChild(o);
        }
        s.addEventListener("change", () => onchange(s.value));
        wrap.appendChild(s);
        controls.appendChild(wrap);
        return s;
      };
      const modes = [["false", "false colour"], ["tone", "tone mapped"]];
      if (meta.maps.some((m) => m.score && m.score.contrast)) modes.push(["contrast", "Q contrast K"]);
      this.modeSelect = select("view", modes, this.mode, (v) => this.setMode(v));
      select("colours", meta.colour_maps.map((n) => [n, n]), this.colourMap, (v) => { this.colourMap = v; this.render(); });
      if (meta.maps.length > 1) {
        const a = meta.maps[0].name, b = meta.maps[1].name;
        this.layoutSelect = select("layout", [["side", a + " | " + b], ["ratio", "ratio " + b + " / " + a], ["a", a], ["b", b]],
          this.layout, (v) => this.setLayout(v));
      }
      const number = (label, value, onchange) => {
        const wrap = el("label", null, label + " ");
        const input = el("input", { type: "number", step: "any", value: String(value) });
        input.addEventListener("change", () => { const v = parseFloat(input.value); if (v > 0) onchange(v); });
        wrap.appendChild(input);
        controls.appendChild(wrap);
        return input;
      };
      this.minInput = number("min [cd/m²]", fmt(this.range[0], 3), (v) => { this.range[0] = v; this.render(); });
      this.maxInput = number("max [cd/m²]", fmt(this.range[1], 3), (v) => { this.range[1] = v; this.render(); });
      const button = (text, onclick, title) => {
        const b = el("button", { type: "button", title: title || text }, text);
        b.addEventListener("click", onclick);
        controls.appendChild(b);
        return b;
      };
      button("auto range", () => {
        this.range = meta.maps[0].range.slice();
        this.minInput.value = fmt(this.range[0], 3); this.maxInput.value = fmt(this.range[1], 3);
        this.render();
      });
      const exposureWrap = el("label", null, "exposure [EV] ");
      const exposure = el("input", { type: "range", min: "-6", max: "6", step: "0.5", value: "0" });
      exposure.addEventListener("input", () => { this.exposure = parseFloat(exposure.value); if (this.mode === "tone") this.render(); });
      exposureWrap.appendChild(exposure);
      controls.appendChild(exposureWrap);
      const checkbox = (label, key) => {
        const wrap = el("label", null, "");
        const box = el("input", { type: "checkbox" });
        box.checked = this[key];
        box.addEventListener("change", () => { this[key] = box.checked; this.render(); });
        wrap.appendChild(box);
        wrap.appendChild(document.createTextNode(" " + label));
        controls.appendChild(wrap);
      };
      if (meta.maps.some((m) => m.score)) checkbox("glare sources", "showSources");
      if (meta.maps.some((m) => m.score && m.score.band)) checkbox("band (-B)", "showBand");
      if (meta.maps.some((m) => m.score && m.score.zones)) checkbox("zones (-l/-L)", "showZones");
      this.toolSelect = select("tool", [["probe", "probe / pin (click), pan (drag)"], ["circle", "circle region (drag)"],
        ["polygon", "polygon region (click vertices, double-click to close)"]], this.tool,
      (v) => this.setTool(v));
      button("fit", () => this.fit(), "fit the map to the panel");
      button("export CSV", () => this.download(), "points and regions as CSV");
      button("clear", () => { this.points = []; this.regions = []; this.updateTables(); this.drawOverlay(); },
        "remove all points and regions");
      c.appendChild(controls);

      this.stage = el("div", { class: "lv-stage" });
      this.panelBox = el("div", { class: "lv-panels" });
      this.stage.appendChild(this.panelBox);
      this.legend = el("canvas", { class: "lv-legend", width: "92", height: "320" });
      this.stage.appendChild(this.legend);
      c.appendChild(this.stage);
      this.probeBox = el("div", { class: "lv-probe" }, "point at the map to read it");
      c.appendChild(this.probeBox);
      this.tableBox = el("div", { class: "lv-tables" });
      c.appendChild(this.tableBox);
      c.appendChild(this.precisionNote());
      this.layoutPanels();
      window.addEventListener("resize", () => { if (this.display) this.fit(); });
    }

    precisionNote() {
      const meta = this.meta, parts = [];
      parts.push("Luminance embedded losslessly as float32 at every pixel" +
        (meta.maps.some((m) => m.uncertainty) ? ", with its per-pixel standard uncertainty" : "") +
        "; the display samples it at screen resolution, the probe and the regions read every pixel." +
        (meta.maps[0].preview ? " While the page loads, a preview (means of " + meta.maps[0].preview.block + " × " +
          meta.maps[0].preview.block + " px blocks) is drawn; the probe and the regions wait for the full data." : ""));
      meta.maps.forEach((m) => {
        if (!m.calibrated) parts.push(m.name + " is uncalibrated (relative scale).");
        else if (!m.uncertainty) parts.push(m.name + ": ± is the calibration's relative standard uncertainty (" +
          fmt(100 * m.calibration_uncertainty, 3) + " %).");
      });
      const g = meta.geometry;
      if (g) {
        const e = g.interpolation_error;
        parts.push("Geometry: direction, pixel solid angle and position index [" + g.position_index_method +
          "] computed by lsadphoto.geometry, embedded every " + g.stride + " px and interpolated bilinearly (" +
          "exact at " + e.exact_pixels + " of " + e.valid_pixels + " valid pixels, where that would miss); σ, τ from that " +
          "direction in the observer frame. Largest error over all valid pixels: direction " + fmt(e.direction_deg, 2) +
          "°, σ " + fmt(e.sigma_deg, 2) + "°, τ " + fmt(e.tau_deg_beyond_1deg, 2) + "° (σ > 1°), P " +
          fmt(e.position_index, 2) + ", ω " + fmt(100 * e.solid_angle_relative, 2) + " % (relative).");
        parts.push("Regions: ω = Σω; mean = Σ Lω / Σω; median ω-weighted; illuminance contribution " +
          "E = Σ L ω cos σ over cos σ > 0 (at the eye, along the line of sight) [lx].");
      } else {
        parts.push("The map has no camera geometry: regions give plain pixel means, no solid angles.");
      }
      if (meta.maps.some((m) => m.score && m.score.contrast)) {
        parts.push("The Q contrast map K is embedded as float16 (3 significant digits).");
      }
      parts.push("lsadphoto " + meta.version + ".");
      return el("p", { class: "lv-note" }, parts.join(" "));
    }

    panelsWanted() {
      const names = this.meta.maps.map((m) => m.name);
      switch (this.layout) {
        case "side": return [{ kind: "map", which: 0, label: names[0] }, { kind: "map", which: 1, label: names[1] }];
        case "ratio": return [{ kind: "ratio", which: 0, label: names[1] + " / " + names[0] }];
        case "b": return [{ kind: "map", which: 1, label: names[1] }];
        default: return [{ kind: "map", which: 0, label: names[0] }];
      }
    }

    /** The mouse's tool: "probe" (click pins, drag pans), "circle" or "polygon". */
    setTool(tool) {
      this.tool = tool;
      this.draft = null;
      if (this.toolSelect) this.toolSelect.value = tool;
      this.drawOverlay();
    }

    /** Show "false" (false colour), "tone" (tone mapped) or "contrast" (the Q contrast map K). */
    async setMode(mode) {
      if (mode === "contrast") await this.loadContrast();
      this.mode = mode;
      if (this.modeSelect) this.modeSelect.value = mode;
      this.render();
    }

    /** Show "side" (both maps), "ratio" (second / first), "a" or "b" (one map). */
    setLayout(layout) {
      this.layout = layout;
      if (this.layoutSelect) this.layoutSelect.value = layout;
      this.layoutPanels();
      this.fit();
    }

    layoutPanels() {
      this.panelBox.textContent = "";
      this.panels = this.panelsWanted().map((spec) => {
        const box = el("div", { class: "lv-panel" });
        const base = el("canvas", { class: "lv-base" });
        const over = el("canvas", { class: "lv-over" });
        box.appendChild(base); box.appendChild(over);
        box.appendChild(el("div", { class: "lv-label" }, spec.label));
        this.panelBox.appendChild(box);
        const panel = Object.assign({ box: box, base: base, over: over }, spec);
        this.attachEvents(panel);
        return panel;
      });
    }

    fit() {
      if (!this.panels.length) return;
      const room = Math.max(160, Math.floor(this.panelBox.clientWidth / this.panels.length) - 6);
      const height = Math.max(120, Math.min(Math.floor(room * this.rows / this.cols), Math.floor(window.innerHeight * 0.7)));
      const width = Math.max(160, Math.min(room, Math.ceil(height * this.cols / this.rows)));
      for (const p of this.panels) {
        for (const canvas of [p.base, p.over]) { canvas.width = width; canvas.height = height; }
        p.box.style.width = width + "px"; p.box.style.height = height + "px";
      }
      this.scale = Math.min(width / this.cols, height / this.rows);
      this.originCol = -0.5 - (width / this.scale - this.cols) / 2;
      this.originRow = -0.5 - (height / this.scale - this.rows) / 2;
      this.render();
    }

    toImage(x, y) { return [this.originRow + y / this.scale, this.originCol + x / this.scale]; }
    toScreen(row, col) { return [(col - this.originCol) * this.scale, (row - this.originRow) * this.scale]; }

    zoom(factor, x, y) {
      const [row, col] = this.toImage(x, y);
      const fitScale = Math.min(this.panels[0].base.width / this.cols, this.panels[0].base.height / this.rows);
      this.scale = Math.min(64, Math.max(fitScale / 2, this.scale * factor));
      this.originRow = row - y / this.scale;
      this.originCol = col - x / this.scale;
      this.render();
    }

    // --- drawing ---

    render() {
      if (!this.display) return;
      const t0 = performance.now();
      for (const p of this.panels) this.renderPanel(p);
      this.renderLegend();
      this.drawOverlay();
      this.renderMs = performance.now() - t0;
    }

    renderPanel(panel) {
      const ctx = panel.base.getContext("2d");
      const w = panel.base.width, h = panel.base.height;
      const image = ctx.createImageData(w, h);
      const out = new Uint32Array(image.data.buffer);
      const rowIndex = new Int32Array(h), colIndex = new Int32Array(w);
      // Map pixels under the screen's, then the drawn array's (the preview's block of them).
      const which = panel.which, shown = this.display, d = shown[which], block = d.block;
      for (let y = 0; y < h; y++) { const r = Math.round(this.originRow + (y + 0.5) / this.scale); rowIndex[y] = r >= 0 && r < this.rows ? Math.floor(r / block) : -1; }
      for (let x = 0; x < w; x++) { const c = Math.round(this.originCol + (x + 0.5) / this.scale); colIndex[x] = c >= 0 && c < this.cols ? Math.floor(c / block) : -1; }
      const pack = (r, g, b) => (255 << 24) | (b << 16) | (g << 8) | r; // little-endian RGBA
      const background = pack(250, 250, 250), unknown = pack(128, 128, 128);
      const lut = new Uint32Array(256);
      let table, lo, hi, values, transform;
      // The overlays of the full-resolution data (none over a preview).
      const m = this.isReady ? this.maps[which] : null;
      if (panel.kind === "ratio") {
        table = this.tables.ratio; lo = -1; hi = 1;
        const A = shown[0].L, B = shown[1].L;
        values = null;
        transform = (i) => { const v = B[i] / A[i]; return v > 0 && Number.isFinite(v) ? Math.log2(v) : NaN; };
      } else if (this.mode === "contrast" && m && m.contrast) {
        table = this.tables.contrast;
        const range = m.meta.score.contrast_range || [1, 10];
        lo = Math.log10(range[0]); hi = Math.log10(range[1]);
        const half = halfToFloat(), K = m.contrast;
        transform = (i) => { const v = half[K[i]]; return v > 0 ? Math.log10(v) : NaN; };
      } else if (this.mode === "tone") {
        table = null;
        values = d.L;
      } else {
        table = this.tables[this.colourMap];
        lo = Math.log10(this.range[0]); hi = Math.log10(this.range[1]);
        const L = d.L;
        transform = (i) => { const v = L[i]; return v > 0 ? Math.log10(v) : (v === 0 ? -Infinity : NaN); };
      }
      if (table) for (let k = 0; k < 256; k++) lut[k] = pack(table[3 * k], table[3 * k + 1], table[3 * k + 2]);
      const span = hi - lo;
      const key = 0.18 * Math.pow(2, this.exposure) / this.meta.maps[which].log_average;
      const labels = m && this.showSources && panel.kind === "map" ? m.labels : null;
      const band = m && this.showBand && panel.kind === "map" ? m.band : null;
      const zones = m && this.showZones && panel.kind === "map" ? m.zones : null;
      const palette = this.tables.sources;
      // Band: a magenta veil; zone 1 a white, zone 2 a yellow one (a quarter each).
      const veil = (colour, r, g, b) => pack(((colour & 255) * 3 + r) >> 2,
        ((((colour >> 8) & 255) * 3) + g) >> 2, ((((colour >> 16) & 255) * 3) + b) >> 2);
      for (let y = 0; y < h; y++) {
        const r = rowIndex[y], line = y * w;
        if (r < 0) { out.fill(background, line, line + w); continue; }
        const rowStart = r * d.cols;
        for (let x = 0; x < w; x++) {
          const c = colIndex[x];
          if (c < 0) { out[line + x] = background; continue; }
          const i = rowStart + c;
          let colour;
          if (table) {
            const t = transform(i);
            if (Number.isNaN(t)) colour = unknown;
            else {
              let k = Math.floor(255.999 * (t - lo) / span);
              k = k < 0 ? 0 : k > 255 ? 255 : k;
              colour = lut[k];
            }
          } else {
            const v = values[i];
            if (!(v >= 0)) colour = unknown;
            else {
              const s = v * key, d = s / (1 + s);
              const g = Math.round(255 * Math.pow(d, 1 / 2.2));
              colour = pack(g, g, g);
            }
          }
          if (zones && zones[i]) colour = zones[i] === 1 ? veil(colour, 255, 255, 255) : veil(colour, 255, 214, 0);
          if (band && band[i]) colour = veil(colour, 255, 0, 255);
          if (labels) {
            const label = labels[i];
            if (label > 0) {
              const q = 3 * ((label - 1) % 10);
              colour = pack((((colour & 255) + palette[q]) >> 1), ((((colour >> 8) & 255) + palette[q + 1]) >> 1),
                ((((colour >> 16) & 255) + palette[q + 2]) >> 1));
            }
          }
          out[line + x] = colour;
        }
      }
      ctx.putImageData(image, 0, 0);
    }

    legendSpec() {
      const panel = this.panels[0];
      if (panel.kind === "ratio") return { table: this.tables.ratio, lo: 0.5, hi: 2, unit: "ratio" };
      if (this.mode === "contrast") {
        const score = this.meta.maps[panel.which].score;
        const range = (score && score.contrast_range) || [1, 10];
        return { table: this.tables.contrast, lo: range[0], hi: range[1], unit: "K [1/rad]" };
      }
      if (this.mode === "tone") return null;
      return { table: this.tables[this.colourMap], lo: this.range[0], hi: this.range[1], unit: "cd/m²" };
    }

    renderLegend() {
      const ctx = this.legend.getContext("2d"), W = this.legend.width, H = this.legend.height;
      ctx.clearRect(0, 0, W, H);
      const spec = this.legendSpec();
      if (!spec) { ctx.fillStyle = "#333"; ctx.font = "11px sans-serif"; ctx.fillText("tone mapped", 4, 14); return; }
      const top = 20, bottom = H - 10, x0 = 4, barW = 16;
      for (let y = top; y < bottom; y++) {
        const k = Math.min(255, Math.floor(256 * (bottom - 1 - y) / (bottom - top)));
        const t = spec.table;
        ctx.fillStyle = "rgb(" + t[3 * k] + "," + t[3 * k + 1] + "," + t[3 * k + 2] + ")";
        ctx.fillRect(x0, y, barW, 1);
      }
      ctx.fillStyle = "#222"; ctx.font = "11px sans-serif";
      ctx.fillText(spec.unit, 2, 12);
      const llo = Math.log10(spec.lo), lhi = Math.log10(spec.hi);
      const ticks = [];
      const steps = lhi - llo > 4 ? [1] : lhi - llo > 1.5 ? [1, 2, 5] : [1, 1.5, 2, 3, 5, 7];
      for (let e = Math.floor(llo) - 1; e <= Math.ceil(lhi); e++) {
        for (const s of steps) { const v = s * Math.pow(10, e); if (v >= spec.lo * 0.999 && v <= spec.hi * 1.001) ticks.push(v); }
      }
      for (const v of ticks) {
        const y = bottom - (Math.log10(v) - llo) / (lhi - llo) * (bottom - top);
        ctx.fillRect(x0 + barW, Math.round(y), 4, 1);
        ctx.fillText(fmt(v, 3), x0 + barW + 6, Math.round(y) + 4);
      }
    }

    drawOverlay() {
      if (!this.display) return;
      for (const p of this.panels) {
        const ctx = p.over.getContext("2d");
        ctx.clearRect(0, 0, p.over.width, p.over.height);
        ctx.lineWidth = 1.5;
        ctx.font = "bold 12px sans-serif";
        const outline = (draw, colour) => {
          ctx.strokeStyle = "rgba(0,0,0,0.8)"; ctx.lineWidth = 3.5; draw(); ctx.stroke();
          ctx.strokeStyle = colour; ctx.lineWidth = 1.5; draw(); ctx.stroke();
        };
        const label = (text, x, y, colour) => {
          ctx.lineWidth = 3; ctx.strokeStyle = "rgba(0,0,0,0.85)"; ctx.strokeText(text, x, y);
          ctx.fillStyle = colour; ctx.fillText(text, x, y);
        };
        if (this.showSources && p.kind === "map") {
          this.sources(p.which).forEach((s, k) => {
            const [x, y] = this.toScreen(s.row, s.col);
            outline(() => { ctx.beginPath(); ctx.arc(x, y, 7, 0, 2 * Math.PI); }, "#ffffff");
            label(String(k + 1), x + 9, y - 6, "#ffffff");
          });
        }
        for (const r of this.regions.concat(this.draft ? [this.draft] : [])) {
          const colour = r === this.draft ? "#ffd33d" : "#39ff14";
          if (r.shape === "circle") {
            const [x, y] = this.toScreen(r.row, r.col);
            outline(() => { ctx.beginPath(); ctx.arc(x, y, Math.max(1, r.radius * this.scale), 0, 2 * Math.PI); }, colour);
            if (r.id) label("R" + r.id, x + r.radius * this.scale + 3, y, colour);
          } else if (r.points.length) {
            outline(() => {
              ctx.beginPath();
              r.points.forEach((q, k) => { const [x, y] = this.toScreen(q[0], q[1]); if (k) ctx.lineTo(x, y); else ctx.moveTo(x, y); });
              if (r !== this.draft) ctx.closePath();
            }, colour);
            if (r.id) { const [x, y] = this.toScreen(r.points[0][0], r.points[0][1]); label("R" + r.id, x + 4, y - 4, colour); }
          }
        }
        for (const q of this.points) {
          const [x, y] = this.toScreen(q.row, q.col);
          outline(() => { ctx.beginPath(); ctx.moveTo(x - 6, y); ctx.lineTo(x + 6, y); ctx.moveTo(x, y - 6); ctx.lineTo(x, y + 6); }, "#00e5ff");
          label("P" + q.id, x + 6, y - 6, "#00e5ff");
        }
        if (this.probe) {
          const [x, y] = this.toScreen(this.probe.row, this.probe.col);
          const size = Math.max(this.scale, 4);
          outline(() => { ctx.beginPath(); ctx.rect(x - size / 2, y - size / 2, size, size); }, "#ffffff");
        }
      }
    }

    // --- interaction ---

    attachEvents(panel) {
      const canvas = panel.over;
      let drag = null;
      const position = (event) => {
        const rect = canvas.getBoundingClientRect();
        return [event.clientX - rect.left, event.clientY - rect.top];
      };
      canvas.addEventListener("wheel", (event) => {
        event.preventDefault();
        const [x, y] = position(event);
        this.zoom(event.deltaY < 0 ? 1.25 : 0.8, x, y);
      }, { passive: false });
      canvas.addEventListener("contextmenu", (event) => event.preventDefault());
      canvas.addEventListener("mousedown", (event) => {
        const [x, y] = position(event);
        const [row, col] = this.toImage(x, y);
        const pan = event.button !== 0 || event.shiftKey || this.tool === "probe";
        drag = { x: x, y: y, moved: false, pan: pan, row: row, col: col };
        if (!pan && this.tool === "circle") this.draft = { shape: "circle", row: Math.round(row), col: Math.round(col), radius: 0 };
      });
      window.addEventListener("mouseup", (event) => {
        if (!drag) return;
        const d = drag; drag = null;
        if (d.pan && !d.moved && this.tool === "probe" && event.target === canvas) {
          this.pin(Math.round(d.row), Math.round(d.col));
        } else if (!d.pan && this.tool === "circle" && this.draft) {
          const c = this.draft; this.draft = null;
          if (c.radius >= 0.5) this.addCircle(c.row, c.col, c.radius); else this.drawOverlay();
        } else if (!d.pan && !d.moved && this.tool === "polygon" && event.target === canvas) {
          if (!this.draft) this.draft = { shape: "polygon", points: [] };
          this.draft.points.push([d.row, d.col]);
          this.drawOverlay();
        }
      });
      canvas.addEventListener("dblclick", () => {
        if (this.tool === "polygon" && this.draft) {
          const pts = this.draft.points;
          // A double click adds its point twice (two clicks): drop the repeat.
          if (pts.length > 1) pts.pop();
          this.draft = null;
          if (pts.length >= 3) this.addPolygon(pts); else this.drawOverlay();
        }
      });
      canvas.addEventListener("mousemove", (event) => {
        const [x, y] = position(event);
        const [row, col] = this.toImage(x, y);
        if (drag) {
          if (Math.abs(x - drag.x) + Math.abs(y - drag.y) > 3) drag.moved = true;
          if (drag.pan && drag.moved) {
            this.originCol -= (x - drag.x) / this.scale; this.originRow -= (y - drag.y) / this.scale;
            drag.x = x; drag.y = y;
            this.render();
            return;
          }
          if (this.tool === "circle" && this.draft) {
            this.draft.radius = Math.hypot(row - this.draft.row, col - this.draft.col);
          }
        }
        this.setProbe(Math.round(row), Math.round(col));
      });
      canvas.addEventListener("mouseleave", () => { this.probe = null; this.drawOverlay(); });
    }

    setProbe(row, col) {
      if (this.index(row, col) < 0) { this.probe = null; this.drawOverlay(); return; }
      this.probe = { row: row, col: col };
      this.drawOverlay();
      this.probeBox.textContent = "";
      if (!this.isReady) {
        this.probeBox.textContent = "row, col " + row + ", " + col + ": loading the full-resolution data… (the probe reads them, never the preview)";
        return;
      }
      this.probeBox.appendChild(this.probeTable(row, col));
    }

    probeTable(row, col) {
      const table = el("table");
      const add = (name, value) => { const tr = el("tr"); tr.appendChild(el("th", null, name)); tr.appendChild(el("td", null, value)); table.appendChild(tr); };
      add("row, col", row + ", " + col);
      this.maps.forEach((m, k) => {
        const L = this.valueAt(row, col, k), U = this.uncertaintyAt(row, col, k);
        add(m.meta.name + " L [cd/m²]", fmt(L, 5) + (Number.isFinite(U) ? " ± " + fmt(U, 2) : ""));
        const label = this.sourceLabelAt(row, col, k);
        if (label > 0) add(m.meta.name + " glare source", "#" + label);
        if (m.zones) add(m.meta.name + " zone", this.zoneAt(row, col, k) ? String(this.zoneAt(row, col, k)) : "outside");
        if (m.band) add(m.meta.name + " band", this.bandAt(row, col, k) ? "inside" : "outside");
        if (m.contrast) add(m.meta.name + " K [1/rad]", fmt(this.contrastAt(row, col, k), 3));
      });
      if (this.maps.length > 1) add("ratio " + this.maps[1].meta.name + " / " + this.maps[0].meta.name,
        fmt(this.valueAt(row, col, 1) / this.valueAt(row, col, 0), 4));
      const g = this.geometryAt(row, col);
      if (g) {
        add("direction (x, y, z)", g.direction.map((v) => v.toFixed(4)).join(", "));
        add("σ, τ [°]", fmt(deg(g.sigma), 4) + ", " + fmt(deg(g.tau), 4));
        add("position index", fmt(g.positionIndex, 4));
        add("pixel solid angle [sr]", fmt(g.solidAngle, 4));
      } else if (this.geometry) add("geometry", "outside the valid image");
      return table;
    }

    updateTables() {
      if (!this.isReady) return;
      const box = this.tableBox;
      box.textContent = "";
      const table = (title, headers, rows) => {
        if (!rows.length) return;
        box.appendChild(el("h4", null, title));
        const t = el("table");
        const tr = el("tr"); headers.forEach((h) => tr.appendChild(el("th", null, h))); t.appendChild(tr);
        rows.forEach((row) => { const r = el("tr"); row.forEach((v) => r.appendChild(el("td", null, v))); t.appendChild(r); });
        box.appendChild(t);
      };
      const mapNames = this.maps.length > 1;
      const pointRows = [], regionRows = [];
      this.maps.forEach((m, k) => {
        for (const p of this.points) {
          const q = this.pointRecord(p, k);
          pointRows.push(["P" + p.id].concat(mapNames ? [m.meta.name] : [], [p.row + ", " + p.col,
            fmt(q.L, 5) + (Number.isFinite(q.U) ? " ± " + fmt(q.U, 2) : ""),
            q.g ? fmt(deg(q.g.sigma), 4) : "—", q.g ? fmt(deg(q.g.tau), 4) : "—", q.g ? fmt(q.g.positionIndex, 4) : "—"]));
        }
        for (const r of this.regions) {
          const s = this.regionStats(r, k);
          regionRows.push(["R" + r.id].concat(mapNames ? [m.meta.name] : [], [r.shape, String(s.n), fmt(s.solidAngle, 4),
            fmt(s.mean, 4), fmt(s.median, 4), fmt(s.max, 4), fmt(s.illuminance, 4)]));
        }
      });
      const mapHead = mapNames ? ["map"] : [];
      table("Points", ["point"].concat(mapHead, ["row, col", "L [cd/m²]", "σ [°]", "τ [°]", "P"]), pointRows);
      table("Regions", ["region"].concat(mapHead, ["shape", "pixels", "ω [sr]", "mean [cd/m²]", "median [cd/m²]",
        "max [cd/m²]", "E contribution [lx]"]), regionRows);
      this.maps.forEach((m) => {
        const score = m.meta.score;
        if (!score) return;
        const rows = score.sources.map((s, k) => [String(k + 1), fmt(s.luminance, 5), fmt(s.solid_angle, 4),
          fmt(s.position_index, 3), fmt(s.sigma_deg, 3), fmt(s.tau_deg, 3), String(s.n_pixels),
          fmt(s.row, 5) + ", " + fmt(s.col, 5)]);
        table("Glare sources of " + m.meta.name + " (lsadphoto score)", ["#", "L [cd/m²]", "ω [sr]", "P", "σ [°]", "τ [°]",
          "pixels", "centre row, col"], rows);
        const regionRow = (name, r) => [name, fmt(r.solid_angle, 4), fmt(r.mean, 4), fmt(r.median, 4),
          fmt(r.max, 4), r.illuminance === undefined ? "—" : fmt(r.illuminance, 4), String(r.n_pixels)];
        const analysed = [];
        if (score.band_stats) analysed.push(regionRow("band ±" + fmt(score.band_deg, 3) + "°", score.band_stats));
        (score.zone_stats || []).forEach((z, k) => analysed.push(regionRow("zone " + (k + 1), z)));
        table("Band and zones of " + m.meta.name + " (lsadphoto score)", ["region", "ω [sr]", "mean [cd/m²]",
          "median [cd/m²]", "max [cd/m²]", "E [lx]", "pixels"], analysed);
        const v = score.values, u = score.uncertainty || {};
        const keys = [["ugr_pixel", "UGR pixel"], ["ugr_grouped", "UGR grouped"], ["q", "Q"], ["dgp", "DGP"],
          ["vertical_illuminance", "E_v [lx]"], ["background_luminance", "L_b [cd/m²]"]];
        const facts = keys.filter(([key]) => v[key] !== undefined && v[key] !== null)
          .map(([key, name]) => name + " " + fmt(v[key], 4) + (u[key] ? " ± " + fmt(u[key], 2) : ""));
        if (facts.length) box.appendChild(el("p", { class: "lv-facts" }, m.meta.name + ": " + facts.join("; ")));
        for (const note of score.notes || []) box.appendChild(el("p", { class: "lv-facts" }, "note: " + note));
      });
    }

    download() {
      if (!this.isReady) { this.status.textContent = "the CSV waits for the full-resolution data, still loading…"; return; }
      const blob = new Blob([this.csv()], { type: "text/csv" });
      const link = el("a", { href: URL.createObjectURL(blob), download: "lsadphoto-view.csv" });
      document.body.appendChild(link);
      link.click();
      link.remove();
    }
  }

  /** Resolves when the document is parsed (every embedded array is in it). */
  function documentParsed() {
    return new Promise((resolve) => {
      if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", () => resolve(), { once: true });
      else resolve();
    });
  }

  function start(container) {
    if (container.lsadViewer) return;
    const viewer = new Viewer(container);
    container.lsadViewer = viewer;
    viewers.push(viewer);
    if (!window.lsadViewer) window.lsadViewer = viewer;
    if (container.dataset.lazy === "yes" && "IntersectionObserver" in window) {
      const observer = new IntersectionObserver((entries) => {
        if (entries.some((e) => e.isIntersecting)) { observer.disconnect(); viewer.load(); }
      }, { rootMargin: "300px" });
      observer.observe(container);
    } else {
      viewer.load();
    }
  }

  // A viewer's fragment calls this right after its preview, while the page is still parsed.
  window.lsadViewerStart = start;
  function startAll() { document.querySelectorAll(".lsad-viewer").forEach(start); }
  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", startAll);
  else startAll();
})();
