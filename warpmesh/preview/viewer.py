"""The WebGL viewer shared by the HTML export and the notebook widget (JavaScript, no dependency).

Why this route
--------------
A mesh page must open anywhere (a browser with no network, a CI screenshot, an e-mail
attachment) and a notebook view must take new buffers at edit rate. pyvista's
``export_html`` goes through trame and vtk.js: the page embeds the vtk.js bundle (several
MB of script before any geometry) and the install adds trame, trame-vtk, trame-vuetify
and their web stacks; three.js is another few hundred KB of script to ship or fetch. A
triangle surface needs far less: the ~6 KB of JavaScript below draw it with WebGL2 (or
WebGL1 with 32-bit indices), smooth vertex normals computed in the page, a head light,
and an orbit camera (drag to turn, wheel to zoom, double-click to refit). The HTML page
inlines it with the mesh as base64 float32/uint32 buffers (about 16 bytes per triangle);
the widget ships it once as an anywidget module and then sends only the buffers, so a
new mesh replaces the buffers in place and the camera stays where the user left it.

Measured here (2026-12-02, CPython 3.11, 2 cores): the trame route's wheels are 8.0 MB
(trame 28 KB, trame-client 556 KB, trame-server 48 KB, trame-vtk 836 KB, trame-vuetify
6.5 MB, wslink 40 KB; aiohttp and the rest of wslink's dependencies on top), and its static
page template alone is 1.05 MB of vtk.js. This route: the HTML export needs no package at
all (6.8 KB of script); the widget needs anywidget and ipywidgets (wheels 3.4 MB with
psygnal, widgetsnbextension and jupyterlab_widgets; 7.5 MB installed), which a notebook
user mostly has already. For the part at 128³ (94 k triangles) the page is 2.3 MB and is
written in about 4 ms; sending new buffers to the widget takes about 5 ms; headless
Chromium (SwiftShader WebGL) draws the page in under 3 s from a cold start.

``VIEWER_JS`` defines ``createWarpmeshViewer(canvas, options)`` (options: ``color``,
``background``, ``box`` = [lo, hi] to frame instead of the first mesh's bounding box,
``top`` to look down the z axis, for 2D meshes),
which returns an object with ``setMesh(positions: Float32Array, indices: Uint32Array)``,
``fit()`` and ``draw()``.

Example
-------
>>> from warpmesh.preview.viewer import VIEWER_JS, WIDGET_ESM
>>> "createWarpmeshViewer" in VIEWER_JS and WIDGET_ESM.startswith(VIEWER_JS)
True
"""

VIEWER_JS = r"""
function createWarpmeshViewer(canvas, options) {
  options = options || {};
  const color = options.color || [0.55, 0.72, 0.9];
  const background = options.background || [1, 1, 1];
  let gl = canvas.getContext("webgl2", {antialias: true, preserveDrawingBuffer: true});
  const webgl2 = !!gl;
  if (!gl) {
    gl = canvas.getContext("webgl", {antialias: true, preserveDrawingBuffer: true});
    if (!gl) throw new Error("warpmesh viewer: WebGL is not available");
    if (!gl.getExtension("OES_element_index_uint")) throw new Error("warpmesh viewer: 32-bit indices unsupported");
  }
  const vs = `attribute vec3 position; attribute vec3 normal;
    uniform mat4 mv; uniform mat4 proj; varying vec3 n_eye; varying vec3 p_eye;
    void main() { vec4 p = mv * vec4(position, 1.0); p_eye = p.xyz;
      n_eye = (mv * vec4(normal, 0.0)).xyz; gl_Position = proj * p; }`;
  const fs = `precision highp float; varying vec3 n_eye; varying vec3 p_eye; uniform vec3 color;
    void main() { vec3 n = normalize(n_eye); vec3 v = normalize(-p_eye);
      float d = abs(dot(n, v)); vec3 h = normalize(v + vec3(0.3, 0.4, 0.0));
      float s = pow(max(abs(dot(n, h)), 0.0), 40.0);
      gl_FragColor = vec4(color * (0.25 + 0.75 * d) + vec3(0.25 * s), 1.0); }`;
  function shader(type, src) {
    const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  const prog = gl.createProgram();
  gl.attachShader(prog, shader(gl.VERTEX_SHADER, vs));
  gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, fs));
  gl.bindAttribLocation(prog, 0, "position"); gl.bindAttribLocation(prog, 1, "normal");
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  const loc = {mv: gl.getUniformLocation(prog, "mv"), proj: gl.getUniformLocation(prog, "proj"),
               color: gl.getUniformLocation(prog, "color")};
  const buf = {pos: gl.createBuffer(), nrm: gl.createBuffer(), idx: gl.createBuffer()};
  let count = 0, center = [0, 0, 0], radius = 1, fitted = false;
  if (options.box) {  // a fixed box to frame (a preview's bounds): the camera does not follow the mesh
    const lo = options.box[0], hi = options.box[1];
    center = [0, 1, 2].map(j => 0.5 * (lo[j] + hi[j]));
    radius = 0.5 * Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    fitted = true;
  }
  // camera: orbit angles around the centre, distance in units of the radius
  // from (1, 1, 1) as pyvista's "iso" (so a volume mesh's cut, which faces +x, is seen), or from above
  const cam = options.top ? {yaw: 0, pitch: 1.55, dist: 2.6} : {yaw: 2.356, pitch: 0.615, dist: 2.6};

  function normals(p, t) {
    const n = new Float32Array(p.length);
    for (let k = 0; k < t.length; k += 3) {
      const a = 3 * t[k], b = 3 * t[k + 1], c = 3 * t[k + 2];
      const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
      const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
      const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      for (const i of [a, b, c]) { n[i] += nx; n[i + 1] += ny; n[i + 2] += nz; }
    }
    return n;
  }
  function setMesh(positions, indices) {
    gl.bindBuffer(gl.ARRAY_BUFFER, buf.pos); gl.bufferData(gl.ARRAY_BUFFER, positions, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, buf.nrm); gl.bufferData(gl.ARRAY_BUFFER, normals(positions, indices), gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buf.idx); gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indices, gl.DYNAMIC_DRAW);
    count = indices.length;
    if (!fitted && positions.length) { fit(positions); }
    draw();
  }
  function fit(p) {
    if (p) {
      const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
      for (let i = 0; i < p.length; i += 3)
        for (let j = 0; j < 3; j++) { lo[j] = Math.min(lo[j], p[i + j]); hi[j] = Math.max(hi[j], p[i + j]); }
      center = [0, 1, 2].map(j => 0.5 * (lo[j] + hi[j]));
      radius = Math.max(1e-12, 0.5 * Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]));
      fitted = true;
    }
    cam.dist = 2.6;
    draw();
  }
  function matrices() {
    const w = canvas.width, h = canvas.height, f = 1 / Math.tan(0.35), d = cam.dist * radius;
    const near = Math.max(1e-3 * d, d - 2 * radius), far = d + 2 * radius;
    const proj = [f * h / w, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, 2 * far * near / (near - far), 0];
    const cy = Math.cos(cam.yaw), sy = Math.sin(cam.yaw), cp = Math.cos(cam.pitch), sp = Math.sin(cam.pitch);
    // rows of the view rotation (z up in the model): right, up, back
    const r = [cy, sy, 0], u = [-sy * sp, cy * sp, cp], b = [sy * cp, -cy * cp, sp];
    const dot = (a, c) => a[0] * c[0] + a[1] * c[1] + a[2] * c[2];
    const mv = [r[0], u[0], b[0], 0, r[1], u[1], b[1], 0, r[2], u[2], b[2], 0,
                -dot(r, center), -dot(u, center), -dot(b, center) - d, 1];
    return {mv, proj};
  }
  function draw() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(background[0], background[1], background[2], 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!count) return;
    gl.enable(gl.DEPTH_TEST);
    gl.useProgram(prog);
    const m = matrices();
    gl.uniformMatrix4fv(loc.mv, false, m.mv); gl.uniformMatrix4fv(loc.proj, false, m.proj);
    gl.uniform3fv(loc.color, color);
    gl.bindBuffer(gl.ARRAY_BUFFER, buf.pos); gl.enableVertexAttribArray(0); gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, buf.nrm); gl.enableVertexAttribArray(1); gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buf.idx);
    gl.drawElements(gl.TRIANGLES, count, gl.UNSIGNED_INT, 0);
  }
  let drag = null;
  canvas.addEventListener("pointerdown", e => { drag = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener("pointerup", () => { drag = null; });
  canvas.addEventListener("pointermove", e => {
    if (!drag) return;
    cam.yaw -= 0.01 * (e.clientX - drag[0]);
    cam.pitch = Math.max(-1.55, Math.min(1.55, cam.pitch + 0.01 * (e.clientY - drag[1])));
    drag = [e.clientX, e.clientY]; draw();
  });
  canvas.addEventListener("wheel", e => { e.preventDefault(); cam.dist *= Math.exp(0.001 * e.deltaY); draw(); }, {passive: false});
  canvas.addEventListener("dblclick", () => fit());
  if (typeof ResizeObserver !== "undefined") new ResizeObserver(() => draw()).observe(canvas);
  return {setMesh, fit, draw, camera: cam, webgl2};
}
"""

#: the anywidget module: the viewer plus ``render``, which follows the model's buffers
WIDGET_ESM = VIEWER_JS + r"""
function render({ model, el }) {
  const canvas = document.createElement("canvas");
  canvas.style.width = "100%"; canvas.style.height = (model.get("height") || 420) + "px";
  canvas.style.display = "block";
  el.appendChild(canvas);
  const box = model.get("box");
  const viewer = createWarpmeshViewer(canvas, box && box.length ? {box} : {});
  // bytes arrive as DataViews; copied so the typed arrays are aligned
  const copy = v => v.buffer.slice(v.byteOffset, v.byteOffset + v.byteLength);
  function update() {
    viewer.setMesh(new Float32Array(copy(model.get("positions"))), new Uint32Array(copy(model.get("indices"))));
  }
  model.on("change:version", update);  // bumped once both buffers are set
  update();
}
export default { render };
"""
