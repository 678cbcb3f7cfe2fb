// The `pd view` page: runs drawn side by side with WebGL2, one camera and
// one clock. The page's state is mirrored on #status (data-frame,
// data-frames, data-errors, data-ready) so that a test can read it.
"use strict";
(function () {
  const status = document.getElementById("status");
  const errors = [];
  function report(message) {
    errors.push(String(message));
    status.dataset.errors = errors.join(" | ");
  }
  window.addEventListener("error", (e) => report(e.message || e));
  window.addEventListener("unhandledrejection", (e) => report(e.reason));
  const consoleError = console.error.bind(console);
  console.error = (...args) => { report(args.join(" ")); consoleError(...args); };

  const data = JSON.parse(document.getElementById("pd-data").textContent);
  const BODY = [0.87, 0.47, 0.2];
  const COLLIDER = [0.42, 0.55, 0.72];
  const COLLIDER_ALPHA = 0.55;
  const BACKGROUND = [0.957, 0.957, 0.949];
  const CURVES = [["kinetic", "#d62728"], ["elastic", "#2ca02c"], ["gravity", "#1f77b4"], ["total", "#111111"]];
  const DASHES = [[], [6, 4], [2, 3], [10, 3, 2, 3]];

  // ---- data ----
  function decodePositions(run) {
    const bin = atob(run.positions);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    const q = new Uint16Array(bytes.buffer);
    const out = new Float32Array(q.length);
    const n = run.vertices * 3;
    for (let i = 0; i < q.length; i++) {
      const k = i % 3;
      out[i] = data.lo[k] + (q[i] / 65535) * data.extent[k];
    }
    const frames = [];
    for (let f = 0; f < run.times.length; f++) frames.push(out.subarray(f * n, (f + 1) * n));
    return frames;
  }
  for (const run of data.runs) run.frameData = decodePositions(run);
  // The shared clock: the times of the run with the most frames.
  const master = data.runs.reduce((a, b) => (b.times.length > a.times.length ? b : a));
  const clock = master.times;
  function frameAt(run, t) {
    let best = 0;
    for (let i = 0; i < run.times.length; i++) if (run.times[i] <= t + 1e-12) best = i;
    return best;
  }

  // ---- WebGL ----
  const canvas = document.getElementById("gl");
  const gl = canvas.getContext("webgl2", { antialias: true, preserveDrawingBuffer: true });
  if (!gl) { report("WebGL2 is not available in this browser"); return; }
  function shader(type, source) {
    const s = gl.createShader(type);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) report(gl.getShaderInfoLog(s));
    return s;
  }
  const program = gl.createProgram();
  gl.attachShader(program, shader(gl.VERTEX_SHADER, `#version 300 es
    in vec3 position; in vec3 normal; in float scalar;
    uniform mat4 viewProjection; uniform mat4 view;
    out vec3 viewNormal; out float value;
    void main() {
      viewNormal = mat3(view) * normal; value = scalar;
      gl_Position = viewProjection * vec4(position, 1.0);
    }`));
  gl.attachShader(program, shader(gl.FRAGMENT_SHADER, `#version 300 es
    precision highp float;
    in vec3 viewNormal; in float value;
    uniform vec3 base; uniform int coloured; uniform int lit; uniform float alpha;
    out vec4 colour;
    vec3 ramp(float s) {
      s = clamp(s, 0.0, 1.0);
      return mix(mix(vec3(0.15, 0.3, 0.9), vec3(0.95, 0.9, 0.2), smoothstep(0.0, 0.5, s)),
                 vec3(0.9, 0.1, 0.1), smoothstep(0.5, 1.0, s));
    }
    void main() {
      vec3 c = coloured == 1 ? ramp(value) : base;
      float light = 1.0;
      if (lit == 1) {
        vec3 n = normalize(viewNormal);
        // A headlight and a key light from above left; two-sided.
        light = 0.35 + 0.45 * abs(n.z) + 0.3 * max(dot(n, normalize(vec3(-0.4, 0.8, 0.45))), 0.0);
      }
      colour = vec4(c * light, alpha);
    }`));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) report(gl.getProgramInfoLog(program));
  const loc = {
    position: gl.getAttribLocation(program, "position"),
    normal: gl.getAttribLocation(program, "normal"),
    scalar: gl.getAttribLocation(program, "scalar"),
    viewProjection: gl.getUniformLocation(program, "viewProjection"),
    view: gl.getUniformLocation(program, "view"),
    base: gl.getUniformLocation(program, "base"),
    coloured: gl.getUniformLocation(program, "coloured"),
    lit: gl.getUniformLocation(program, "lit"),
    alpha: gl.getUniformLocation(program, "alpha"),
  };

  function normals(positions, triangles) {
    const n = new Float32Array(positions.length);
    for (let t = 0; t < triangles.length; t += 3) {
      const a = triangles[t] * 3, b = triangles[t + 1] * 3, c = triangles[t + 2] * 3;
      const ux = positions[b] - positions[a], uy = positions[b + 1] - positions[a + 1], uz = positions[b + 2] - positions[a + 2];
      const vx = positions[c] - positions[a], vy = positions[c + 1] - positions[a + 1], vz = positions[c + 2] - positions[a + 2];
      const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      for (const v of [a, b, c]) { n[v] += nx; n[v + 1] += ny; n[v + 2] += nz; }
    }
    for (let i = 0; i < n.length; i += 3) {
      const l = Math.hypot(n[i], n[i + 1], n[i + 2]) || 1;
      n[i] /= l; n[i + 1] /= l; n[i + 2] /= l;
    }
    return n;
  }
  function mesh(positions, triangles, lines, dynamic) {
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buffers = {};
    for (const [name, size, values] of [["position", 3, positions], ["normal", 3, normals(positions, triangles)],
                                        ["scalar", 1, new Float32Array(positions.length / 3)]]) {
      const b = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, b);
      gl.bufferData(gl.ARRAY_BUFFER, values, dynamic ? gl.DYNAMIC_DRAW : gl.STATIC_DRAW);
      gl.enableVertexAttribArray(loc[name]);
      gl.vertexAttribPointer(loc[name], size, gl.FLOAT, false, 0, 0);
      buffers[name] = b;
    }
    const tri = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, tri);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, new Uint32Array(triangles), gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    let lineBuffer = null;
    if (lines.length) {
      lineBuffer = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, lineBuffer);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, new Uint32Array(lines), gl.STATIC_DRAW);
    }
    return { vao, buffers, tri, triangles: triangles.length, lineBuffer, lines: lines.length };
  }
  for (const run of data.runs) {
    run.mesh = mesh(run.frameData[0], run.triangles, run.lines, true);
    run.colliderMeshes = run.colliders.map((c) => mesh(new Float32Array(c.positions), c.triangles, [], false));
    // Speed of each vertex from consecutive frames (m/s), and its largest value.
    run.speedMax = 0;
    run.speed = run.frameData.map((x, f) => {
      const g = f === 0 ? Math.min(1, run.frameData.length - 1) : f - 1;
      const dt = Math.abs(run.times[f] - run.times[g]) || 1;
      const s = new Float32Array(run.vertices);
      for (let v = 0; v < run.vertices; v++) {
        s[v] = Math.hypot(x[3 * v] - run.frameData[g][3 * v], x[3 * v + 1] - run.frameData[g][3 * v + 1],
                          x[3 * v + 2] - run.frameData[g][3 * v + 2]) / dt;
        run.speedMax = Math.max(run.speedMax, s[v]);
      }
      return s;
    });
  }

  // ---- camera ----
  const camera = { yaw: 0.6, pitch: 0.5, distance: 1, target: [0, 0, 0], radius: 1 };
  function frameScene() {
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (const run of data.runs) for (const f of run.frameData) for (let i = 0; i < f.length; i++) {
      lo[i % 3] = Math.min(lo[i % 3], f[i]); hi[i % 3] = Math.max(hi[i % 3], f[i]);
    }
    camera.target = [0, 1, 2].map((k) => (lo[k] + hi[k]) / 2);
    camera.radius = Math.max(1e-6, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
    // The narrower of the panel's two fields of view (45 degrees high) holds the sphere.
    const panelAspect = canvas.clientWidth / data.runs.length / Math.max(1, canvas.clientHeight);
    const half = Math.min(Math.PI / 8, Math.atan(Math.tan(Math.PI / 8) * panelAspect));
    camera.distance = camera.radius / Math.sin(half) * 1.05;
  }
  frameScene();
  function multiply(a, b) {
    const o = new Float32Array(16);
    for (let i = 0; i < 4; i++) for (let j = 0; j < 4; j++) {
      let s = 0;
      for (let k = 0; k < 4; k++) s += a[k * 4 + j] * b[i * 4 + k];
      o[i * 4 + j] = s;
    }
    return o;
  }
  function matrices(aspect) {
    const cp = Math.cos(camera.pitch), eye = [
      camera.target[0] + camera.distance * cp * Math.sin(camera.yaw),
      camera.target[1] + camera.distance * Math.sin(camera.pitch),
      camera.target[2] + camera.distance * cp * Math.cos(camera.yaw)];
    const f = [0, 1, 2].map((k) => camera.target[k] - eye[k]);
    const fl = Math.hypot(...f); f.forEach((_, k) => (f[k] /= fl));
    let s = [f[1] * 0 - f[2] * 1, f[2] * 0 - f[0] * 0, f[0] * 1 - f[1] * 0];
    const sl = Math.hypot(...s) || 1; s = s.map((v) => v / sl);
    const u = [s[1] * f[2] - s[2] * f[1], s[2] * f[0] - s[0] * f[2], s[0] * f[1] - s[1] * f[0]];
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    const view = new Float32Array([s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0,
                                   -dot(s, eye), -dot(u, eye), dot(f, eye), 1]);
    const near = Math.max(camera.distance - 3 * camera.radius, camera.distance * 1e-3);
    const far = camera.distance + 10 * camera.radius;
    const t = 1 / Math.tan(Math.PI / 8);
    const projection = new Float32Array([t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (far + near) / (near - far), -1,
                                         0, 0, (2 * far * near) / (near - far), 0]);
    return { view, viewProjection: multiply(projection, view) };
  }

  // ---- state and drawing ----
  const slider = document.getElementById("slider");
  const clockLabel = document.getElementById("clock");
  const colourSelect = document.getElementById("colour");
  const scene = document.getElementById("scene");
  slider.max = String(clock.length - 1);
  slider.setAttribute("max", String(clock.length - 1));
  status.dataset.frames = String(clock.length);
  const labels = data.runs.map((run) => {
    const l = document.createElement("div");
    l.className = "label"; l.textContent = run.label;
    scene.appendChild(l);
    return l;
  });
  let frame = 0, playing = false;

  function draw() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    gl.disable(gl.SCISSOR_TEST);
    gl.viewport(0, 0, w, h);
    gl.clearColor(...BACKGROUND, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.useProgram(program);
    const panels = data.runs.length, pw = Math.floor(w / panels);
    const { view, viewProjection } = matrices(pw / h);
    gl.uniformMatrix4fv(loc.view, false, view);
    gl.uniformMatrix4fv(loc.viewProjection, false, viewProjection);
    const t = clock[frame];
    data.runs.forEach((run, p) => {
      gl.viewport(p * pw, 0, pw, h);
      labels[p].style.left = ((p * pw) / dpr + 6) + "px";
      gl.uniform1i(loc.lit, 1);
      gl.uniform1f(loc.alpha, 1);
      const f = frameAt(run, t), x = run.frameData[f];
      const m = run.mesh;
      gl.bindBuffer(gl.ARRAY_BUFFER, m.buffers.position);
      gl.bufferSubData(gl.ARRAY_BUFFER, 0, x);
      gl.bindBuffer(gl.ARRAY_BUFFER, m.buffers.normal);
      gl.bufferSubData(gl.ARRAY_BUFFER, 0, normals(x, run.triangles));
      const bySpeed = colourSelect.value === "speed";
      if (bySpeed) {
        const s = run.speed[f].map((v) => (run.speedMax > 0 ? v / run.speedMax : 0));
        gl.bindBuffer(gl.ARRAY_BUFFER, m.buffers.scalar);
        gl.bufferSubData(gl.ARRAY_BUFFER, 0, s);
      }
      gl.uniform1i(loc.coloured, bySpeed ? 1 : 0);
      gl.uniform3fv(loc.base, BODY);
      gl.bindVertexArray(m.vao);
      if (m.triangles) gl.drawElements(gl.TRIANGLES, m.triangles, gl.UNSIGNED_INT, 0);
      if (m.lines) {
        gl.uniform1i(loc.lit, 0);
        gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, m.lineBuffer);
        gl.drawElements(gl.LINES, m.lines, gl.UNSIGNED_INT, 0);
      }
      // Colliders after the body, see-through, so that a bowl or a box
      // never hides what moves inside it.
      gl.uniform1i(loc.lit, 1);
      gl.uniform1i(loc.coloured, 0);
      gl.uniform3fv(loc.base, COLLIDER);
      gl.uniform1f(loc.alpha, COLLIDER_ALPHA);
      gl.enable(gl.BLEND);
      gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
      gl.depthMask(false);
      for (const c of run.colliderMeshes) {
        gl.bindVertexArray(c.vao);
        gl.drawElements(gl.TRIANGLES, c.triangles, gl.UNSIGNED_INT, 0);
      }
      gl.depthMask(true);
      gl.disable(gl.BLEND);
      gl.bindVertexArray(null);
    });
    drawPlots(t);
  }

  // ---- plots ----
  function plot(canvasId, title, unit, series, t) {
    const c = document.getElementById(canvasId);
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(c.clientWidth * dpr)), h = Math.max(1, Math.round(c.clientHeight * dpr));
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    const g = c.getContext("2d");
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    const W = w / dpr, H = h / dpr, L = 62, R = 10, T = 18, B = 20;
    g.clearRect(0, 0, W, H);
    g.fillStyle = "#fff"; g.fillRect(0, 0, W, H);
    g.fillStyle = "#222"; g.font = "12px system-ui, sans-serif";
    g.fillText(title + " (" + unit + ")", L, 13);
    if (!series.length) { g.fillStyle = "#777"; g.fillText("not in this run's folder", L, H / 2); return; }
    let t0 = Infinity, t1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    for (const s of series) for (let i = 0; i < s.t.length; i++) {
      t0 = Math.min(t0, s.t[i]); t1 = Math.max(t1, s.t[i]);
      if (Number.isFinite(s.y[i])) { y0 = Math.min(y0, s.y[i]); y1 = Math.max(y1, s.y[i]); }
    }
    if (!(t1 > t0)) t1 = t0 + 1;
    if (!(y1 > y0)) { y1 = y0 + 1; y0 -= 1; }
    const X = (v) => L + ((v - t0) / (t1 - t0)) * (W - L - R), Y = (v) => H - B - ((v - y0) / (y1 - y0)) * (H - T - B);
    g.strokeStyle = "#ccc"; g.strokeRect(L, T, W - L - R, H - T - B);
    g.fillStyle = "#555";
    g.fillText(y1.toPrecision(3), 4, T + 8); g.fillText(y0.toPrecision(3), 4, H - B);
    g.fillText(t0.toPrecision(3) + " s", L, H - 5); g.fillText(t1.toPrecision(3) + " s", W - R - 50, H - 5);
    let legend = L + 8;
    for (const s of series) {
      g.strokeStyle = s.colour; g.setLineDash(s.dash); g.lineWidth = 1.4;
      g.beginPath();
      for (let i = 0; i < s.t.length; i++) (i ? g.lineTo : g.moveTo).call(g, X(s.t[i]), Y(s.y[i]));
      g.stroke();
      g.fillStyle = s.colour; g.fillText(s.label, legend, T + 14);
      legend += g.measureText(s.label).width + 12;
    }
    g.setLineDash([]);
    g.strokeStyle = "#e377c2"; g.lineWidth = 1.5;
    g.beginPath(); g.moveTo(X(t), T); g.lineTo(X(t), H - B); g.stroke();
    c.dataset.t0 = t0; c.dataset.t1 = t1; c.dataset.left = L; c.dataset.right = R;
  }
  const probeColours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"];
  function drawPlots(t) {
    const energy = [], probes = [];
    data.runs.forEach((run, r) => {
      const suffix = data.runs.length > 1 ? " " + run.label : "";
      if (run.metrics) CURVES.forEach(([name, colour]) => energy.push(
        { label: name + suffix, t: run.metrics.time, y: run.metrics[name], colour, dash: DASHES[r % DASHES.length] }));
      if (run.probes) run.probes.series.forEach((s, i) => probes.push(
        { label: s.label + suffix, t: run.probes.time, y: s.distance, colour: probeColours[i % probeColours.length],
          dash: DASHES[r % DASHES.length] }));
    });
    plot("energy", "energy", "J", energy, t);
    plot("probes", "probe distance from start", "m", probes, t);
  }
  for (const id of ["energy", "probes"]) {
    document.getElementById(id).addEventListener("click", (e) => {
      const c = e.currentTarget, r = c.getBoundingClientRect();
      const t0 = +c.dataset.t0, t1 = +c.dataset.t1, L = +c.dataset.left, R = +c.dataset.right;
      if (!(t1 > t0)) return;
      const t = t0 + ((e.clientX - r.left - L) / (r.width - L - R)) * (t1 - t0);
      let best = 0;
      clock.forEach((v, i) => { if (Math.abs(v - t) < Math.abs(clock[best] - t)) best = i; });
      show(best);
    });
  }

  // ---- controls ----
  function show(f, fromHash) {
    frame = Math.max(0, Math.min(clock.length - 1, f | 0));
    slider.value = String(frame);
    slider.setAttribute("value", String(frame));
    clockLabel.textContent = "t = " + clock[frame].toFixed(3) + " s  (frame " + frame + " of " + (clock.length - 1) + ")";
    status.dataset.frame = String(frame);
    if (!fromHash) history.replaceState(null, "", "#frame=" + frame);
    draw();
  }
  function hashFrame() {
    const m = /frame=(\d+)/.exec(location.hash);
    return m ? parseInt(m[1], 10) : null;
  }
  slider.addEventListener("input", () => show(parseInt(slider.value, 10)));
  window.addEventListener("hashchange", () => { const f = hashFrame(); if (f !== null) show(f, true); });
  colourSelect.addEventListener("change", () => draw());
  const playButton = document.getElementById("play");
  let last = 0;
  function tick(now) {
    if (!playing) return;
    if (now - last > 1000 / 25) {
      last = now;
      if (frame >= clock.length - 1) { playing = false; playButton.textContent = "play"; return; }
      show(frame + 1);
    }
    requestAnimationFrame(tick);
  }
  function toggle() {
    playing = !playing;
    playButton.textContent = playing ? "pause" : "play";
    if (playing) { if (frame >= clock.length - 1) show(0); requestAnimationFrame(tick); }
  }
  playButton.addEventListener("click", toggle);
  window.addEventListener("keydown", (e) => {
    if (e.target.tagName === "SELECT") return;
    if (e.key === " ") { toggle(); e.preventDefault(); }
    else if (e.key === "ArrowRight") show(frame + 1);
    else if (e.key === "ArrowLeft") show(frame - 1);
    else if (e.key === "Home") show(0);
    else if (e.key === "End") show(clock.length - 1);
  });
  let drag = null;
  canvas.addEventListener("pointerdown", (e) => { drag = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener("pointerup", () => { drag = null; });
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    camera.yaw -= (e.clientX - drag[0]) * 0.01;
    camera.pitch = Math.max(-1.5, Math.min(1.5, camera.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY];
    draw();
  });
  canvas.addEventListener("wheel", (e) => {
    camera.distance *= Math.exp(e.deltaY * 0.001);
    e.preventDefault();
    draw();
  }, { passive: false });
  canvas.addEventListener("dblclick", () => { frameScene(); draw(); });
  window.addEventListener("resize", () => draw());

  const start = hashFrame();
  show(start === null ? 0 : start, start !== null);
  status.dataset.ready = "1";
})();
