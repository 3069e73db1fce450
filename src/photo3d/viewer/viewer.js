/* photo3d viewer: a small WebGL2 renderer for the one 3D photo embedded in this page.
 *
 * Data (written by photo3d/viewer/html.py, layout in photo3d/viewer/_codec.py), in
 * two script elements of the page:
 *   #photo3d-header (application/json): sizes, fields of view, quantisation bounds,
 *       section offsets, whether to animate
 *   #photo3d-data (application/octet-stream): base64 of one zlib stream: positions
 *       (3 planes of uint16), colours (RGB uint8) or texture coordinates (2 planes
 *       of uint16) plus a JPEG texture (header.texture), labels (uint8), faces
 *       (byte planes of uint32 deltas); with header.overlay, the soft silhouettes:
 *       their positions (as above), RGBA uint8 colours and faces, drawn blended
 *       over the rest (depth tested, not written)
 *
 * Conventions (photo3d.camera): OpenCV axes (x right, y down, z forward); world = the
 * input camera's frame; a pose is a 4x4 camera-from-world matrix. Camera motion here
 * is a translation of a few hundredths of the depth units, like the authors' paths.
 *
 * Hooks for tests and links:
 *   viewer.html#camera=x,y,z&static=1   camera position (world), no auto-animation
 *   window.photo3dViewer: ready (true once the first frame is drawn), firstFrameMs
 *     (since navigation start), timings (stages, ms), frames (drawn so far), error,
 *     setCamera([x, y, z] or 16 numbers of a row-major pose),
 *     setAnimate(bool), position(), pixels() -> {width, height, rgba: base64, rows top first}
 */
'use strict';
(function () {
  // Largest camera offset from its rest position, per axis (depth units): the
  // shifts of the authors' circle path (photo3d.render.paths).
  const RANGE = [0.015, 0.015, 0.05];
  const LOOP_SECONDS = 6; // the authors' videos: 240 frames at 40 fps
  const SPRING = 9; // angular frequency (1/s) of the critically damped camera spring
  const TILT_DEGREES = 15; // device tilt that reaches the edge of RANGE

  const viewer = {
    ready: false, firstFrameMs: null, timings: {}, error: null, frames: 0,
    setCamera, setAnimate, position: () => state.pos.slice(), pixels,
  };
  window.photo3dViewer = viewer;

  const state = {
    rest: [0, 0, 0], // position the camera returns to
    offset: [0, 0, 0], // wanted offset from rest, within +-RANGE
    pos: [0, 0, 0], vel: [0, 0, 0], // current camera position and velocity
    pose: null, // explicit 16-number pose from setCamera, overrides pos
    animate: true, animStart: null,
  };
  const canvas = document.getElementById('photo3d-canvas');
  const message = document.getElementById('photo3d-message');
  let header = null, gl = null, gpu = null, mesh = null;
  let frameRequested = false, lastTime = null;

  function fail(text, err) {
    viewer.error = text + (err ? ': ' + (err.message || err) : '');
    message.textContent = viewer.error;
    message.hidden = false;
    canvas.hidden = true;
  }

  // ---------------------------------------------------------------- decoding

  function base64Bytes(text) {
    text = text.replace(/\s+/g, '');
    if (typeof Uint8Array.fromBase64 === 'function') return Uint8Array.fromBase64(text);
    const table = new Uint8Array(128);
    const alphabet = 'ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/';
    for (let i = 0; i < 64; i++) table[alphabet.charCodeAt(i)] = i;
    let end = text.length;
    while (end > 0 && text[end - 1] === '=') end--;
    const out = new Uint8Array(Math.floor(end * 3 / 4));
    let o = 0, i = 0;
    for (; i + 4 <= end; i += 4) {
      const n = table[text.charCodeAt(i)] << 18 | table[text.charCodeAt(i + 1)] << 12 |
        table[text.charCodeAt(i + 2)] << 6 | table[text.charCodeAt(i + 3)];
      out[o++] = n >> 16; out[o++] = n >> 8 & 255; out[o++] = n & 255;
    }
    let n = 0;
    for (let k = i; k < end; k++) n |= table[text.charCodeAt(k)] << (18 - 6 * (k - i));
    if (end - i >= 2) out[o++] = n >> 16;
    if (end - i === 3) out[o++] = n >> 8 & 255;
    return out;
  }

  async function inflate(bytes) {
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('deflate'));
    return new Response(stream).arrayBuffer();
  }

  // Faces: per face (zigzag(m - previous m), m - a, m - b) as uint32 in 4 byte planes.
  function decodeFaces(buffer, offset, count) {
    const n = 3 * count;
    const b = new Uint8Array(buffer, offset, 4 * n);
    const out = new Uint32Array(n);
    let m = 0;
    for (let i = 0; i < n; i += 3) {
      // '>>> 0' keeps the 32-bit value unsigned
      const z = (b[i] | b[i + n] << 8 | b[i + 2 * n] << 16 | b[i + 3 * n] << 24) >>> 0;
      m += z % 2 ? -(z + 1) / 2 : z / 2;
      const j = i + 1, k = i + 2;
      out[i] = m - ((b[j] | b[j + n] << 8 | b[j + 2 * n] << 16 | b[j + 3 * n] << 24) >>> 0);
      out[j] = m - ((b[k] | b[k + n] << 8 | b[k + 2 * n] << 16 | b[k + 3 * n] << 24) >>> 0);
      out[k] = m;
    }
    return out;
  }

  async function decode() {
    const t0 = performance.now();
    const bytes = base64Bytes(document.getElementById('photo3d-data').textContent);
    const t1 = performance.now();
    const raw = await inflate(bytes);
    const t2 = performance.now();
    const s = header.sections, n = header.vertices;
    const result = {
      position: new Uint16Array(raw, s.position[0], 3 * n),
      faces: decodeFaces(raw, s.faces[0], header.faces),
    };
    const t3 = performance.now();
    if (header.texture) {
      result.uv = new Uint16Array(raw, s.uv[0], 2 * n);
      const jpeg = new Blob([new Uint8Array(raw, s.texture[0], s.texture[1])],
        { type: header.texture.mime });
      // decoded without colour management: the texels are the file's sRGB values
      result.texture = await createImageBitmap(jpeg, {
        imageOrientation: 'none', premultiplyAlpha: 'none', colorSpaceConversion: 'none',
      });
    } else {
      result.color = new Uint8Array(raw, s.color[0], 3 * n);
    }
    if (header.overlay) {
      const k = header.overlay.vertices;
      result.overlay = {
        position: new Uint16Array(raw, s.overlay_position[0], 3 * k),
        color: new Uint8Array(raw, s.overlay_color[0], 4 * k),
        faces: decodeFaces(raw, s.overlay_faces[0], header.overlay.faces),
      };
    }
    Object.assign(viewer.timings, {
      base64Ms: t1 - t0, inflateMs: t2 - t1, facesMs: t3 - t2,
      textureMs: performance.now() - t3,
    });
    return result;
  }

  // --------------------------------------------------------------- rendering

  const VERTEX_SHADER = `#version 300 es
    // Quantised (x/z, y/z, 1/z) of the vertex in the input camera: uint16 / 65535.
    in float a_u, a_v, a_d;
    in vec3 a_color;         // sRGB uint8 / 255, interpolated as-is (as photo3d's renderer)
    uniform vec3 u_lo, u_span;
    uniform mat4 u_view;     // camera-from-world (column-major, as GL expects)
    uniform vec4 u_k;        // 2 fx / w, 2 fy / h, 2 cx / w - 1, 2 cy / h - 1
    uniform vec2 u_z;        // clip z = u_z.x * z + u_z.y
    out vec3 v_color;
    void main() {
      vec3 q = u_lo + u_span * vec3(a_u, a_v, a_d);
      vec3 c = (u_view * vec4(vec3(q.xy, 1.0) / q.z, 1.0)).xyz;
      // Pixel (u, v) = (fx x / z + cx, fy y / z + cy) with v pointing down. GL wants
      // NDC x = 2 u / w - 1 and NDC y = 1 - 2 v / h (its y points up), times the
      // clip w = z so that the GPU's perspective divide gives them back.
      gl_Position = vec4(u_k.x * c.x + u_k.z * c.z,
                         -(u_k.y * c.y + u_k.w * c.z),
                         u_z.x * c.z + u_z.y, c.z);
      v_color = a_color;
    }`;
  const FRAGMENT_SHADER = `#version 300 es
    precision highp float;
    in vec3 v_color;
    out vec4 o_color;
    void main() { o_color = vec4(v_color, 1.0); }`;
  // Textured meshes: the colour attribute becomes texture coordinates (u, v, 0),
  // origin at the texture's top-left (glTF), sampled bilinearly; sRGB values are
  // used as they are, like the vertex colours above.
  const TEXTURED_VERTEX_SHADER = VERTEX_SHADER
    .replace('in vec3 a_color;', 'in vec2 a_uv;')
    .replace('out vec3 v_color;', 'out vec2 v_uv;')
    .replace('v_color = a_color;', 'v_uv = a_uv;');
  const TEXTURED_FRAGMENT_SHADER = `#version 300 es
    precision highp float;
    uniform sampler2D u_texture;
    in vec2 v_uv;
    out vec4 o_color;
    void main() { o_color = vec4(texture(u_texture, v_uv).rgb, 1.0); }`;

  // Soft silhouettes: vertex colours with their alpha (sRGB as above), blended.
  const OVERLAY_VERTEX_SHADER = VERTEX_SHADER
    .replace('in vec3 a_color;', 'in vec4 a_color;')
    .replace('out vec3 v_color;', 'out vec4 v_color;');
  const OVERLAY_FRAGMENT_SHADER = `#version 300 es
    precision highp float;
    in vec4 v_color;
    out vec4 o_color;
    void main() { o_color = v_color; }`;

  function compile(type, source) {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) {
      throw new Error(gl.getShaderInfoLog(shader));
    }
    return shader;
  }

  function link(vertexSource, fragmentSource) {
    const program = gl.createProgram();
    gl.attachShader(program, compile(gl.VERTEX_SHADER, vertexSource));
    gl.attachShader(program, compile(gl.FRAGMENT_SHADER, fragmentSource));
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) {
      throw new Error(gl.getProgramInfoLog(program));
    }
    return program;
  }

  // Uniform locations of a program, its quantisation bounds set.
  function uniforms(program) {
    const uniform = {};
    for (const name of ['u_lo', 'u_span', 'u_view', 'u_k', 'u_z']) {
      uniform[name] = gl.getUniformLocation(program, name);
    }
    gl.useProgram(program);
    const lo = header.position.lo, hi = header.position.hi;
    gl.uniform3fv(uniform.u_lo, lo);
    gl.uniform3fv(uniform.u_span, hi.map((h, i) => h - lo[i]));
    return uniform;
  }

  // The soft silhouettes' program and vertex array (null without them).
  function uploadOverlay() {
    const o = mesh.overlay;
    if (!o) return null;
    const program = link(OVERLAY_VERTEX_SHADER, OVERLAY_FRAGMENT_SHADER);
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const k = header.overlay.vertices;
    const attribute = (name, size, type, offset) => {
      const loc = gl.getAttribLocation(program, name);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, size, type, true, 0, offset);
    };
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, o.position, gl.STATIC_DRAW);
    attribute('a_u', 1, gl.UNSIGNED_SHORT, 0);
    attribute('a_v', 1, gl.UNSIGNED_SHORT, 2 * k);
    attribute('a_d', 1, gl.UNSIGNED_SHORT, 4 * k);
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, o.color, gl.STATIC_DRAW);
    attribute('a_color', 4, gl.UNSIGNED_BYTE, 0);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, o.faces, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    return { program, vao, uniform: uniforms(program), count: 3 * header.overlay.faces };
  }

  function upload() {
    const textured = Boolean(mesh.texture);
    const program = link(textured ? TEXTURED_VERTEX_SHADER : VERTEX_SHADER,
      textured ? TEXTURED_FRAGMENT_SHADER : FRAGMENT_SHADER);
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const n = header.vertices;
    const attribute = (name, size, type, offset) => { // from the bound ARRAY_BUFFER
      const loc = gl.getAttribLocation(program, name);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, size, type, true, 0, offset); // normalised to [0, 1]
    };
    const positions = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, positions);
    gl.bufferData(gl.ARRAY_BUFFER, mesh.position, gl.STATIC_DRAW);
    attribute('a_u', 1, gl.UNSIGNED_SHORT, 0);
    attribute('a_v', 1, gl.UNSIGNED_SHORT, 2 * n);
    attribute('a_d', 1, gl.UNSIGNED_SHORT, 4 * n);
    const colors = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, colors);
    if (textured) {
      const uvs = new Uint16Array(2 * n); // planes (all u, then all v) -> pairs
      for (let i = 0; i < n; i++) { uvs[2 * i] = mesh.uv[i]; uvs[2 * i + 1] = mesh.uv[n + i]; }
      gl.bufferData(gl.ARRAY_BUFFER, uvs, gl.STATIC_DRAW);
      attribute('a_uv', 2, gl.UNSIGNED_SHORT, 0);
      const texture = gl.createTexture();
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, texture);
      gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
      gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGB8, gl.RGB, gl.UNSIGNED_BYTE, mesh.texture);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    } else {
      gl.bufferData(gl.ARRAY_BUFFER, mesh.color, gl.STATIC_DRAW);
      attribute('a_color', 3, gl.UNSIGNED_BYTE, 0);
    }
    const indices = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, indices);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, mesh.faces, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    const uniform = uniforms(program);
    if (textured) gl.uniform1i(gl.getUniformLocation(program, 'u_texture'), 0);
    const overlay = uploadOverlay();
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
    gl.clearColor(0.067, 0.067, 0.067, 1);
    gpu = { program, vao, uniform, overlay };
  }

  // The drawing buffer fills the page while keeping the photo's aspect ratio
  // (CSS pixels times devicePixelRatio, at most 2).
  function resize() {
    const s = Math.min(window.innerWidth / header.width, window.innerHeight / header.height);
    const cssW = Math.max(1, Math.floor(header.width * s));
    const cssH = Math.max(1, Math.floor(header.height * s));
    canvas.style.width = cssW + 'px';
    canvas.style.height = cssH + 'px';
    const dpr = Math.min(window.devicePixelRatio || 1, 2);
    canvas.width = Math.round(cssW * dpr);
    canvas.height = Math.round(cssH * dpr);
  }

  // Intrinsics of the input view (fx = (W / 2) / tan(hfov / 2), principal point at
  // the centre), scaled so the photo covers the drawing buffer, as photo3d's
  // output_intrinsics: a buffer of another shape shows the middle of the photo.
  function projection(w, h) {
    const fx = header.width / 2 / Math.tan(header.hfov / 2);
    const fy = header.height / 2 / Math.tan(header.vfov / 2);
    const s = Math.max(w / header.width, h / header.height);
    const cx = w / 2, cy = h / 2;
    // GL depth: NDC z = (a z + b) / z runs from -1 at `near` to +1 at `far`.
    // Scene depth is 1/hi[2] .. 1/lo[2]; the camera moves by a few hundredths.
    const zMin = 1 / header.position.hi[2], zMax = 1 / Math.max(header.position.lo[2], 1e-9);
    const near = Math.max(0.25 * zMin, 1e-4), far = 2 * zMax + 1;
    return {
      k: [2 * fx * s / w, 2 * fy * s / h, 2 * cx / w - 1, 2 * cy / h - 1],
      z: [(far + near) / (far - near), -2 * far * near / (far - near)],
    };
  }

  function viewMatrix() {
    if (state.pose) { // row-major camera-from-world -> column-major for GL
      const p = state.pose, m = new Float32Array(16);
      for (let r = 0; r < 4; r++) for (let c = 0; c < 4; c++) m[c * 4 + r] = p[r * 4 + c];
      return m;
    }
    const [x, y, z] = state.pos; // camera at pos, axes of the input view: t = -pos
    return new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -x, -y, -z, 1]);
  }

  function draw() {
    const w = canvas.width, h = canvas.height;
    const p = projection(w, h);
    gl.viewport(0, 0, w, h);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    const view = viewMatrix();
    const use = (part) => {
      gl.useProgram(part.program);
      gl.uniformMatrix4fv(part.uniform.u_view, false, view);
      gl.uniform4fv(part.uniform.u_k, p.k);
      gl.uniform2fv(part.uniform.u_z, p.z);
      gl.bindVertexArray(part.vao);
    };
    use(gpu);
    gl.drawElements(gl.TRIANGLES, 3 * header.faces, gl.UNSIGNED_INT, 0);
    if (gpu.overlay) { // the soft silhouettes over what is already drawn behind them
      use(gpu.overlay);
      gl.enable(gl.BLEND);
      gl.depthMask(false);
      gl.drawElements(gl.TRIANGLES, gpu.overlay.count, gl.UNSIGNED_INT, 0);
      gl.depthMask(true);
      gl.disable(gl.BLEND);
    }
    gl.bindVertexArray(null);
    viewer.frames++;
  }

  function pixels() {
    draw(); // the drawing buffer is only readable in the task that drew it
    const w = canvas.width, h = canvas.height, rgba = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, rgba);
    const flipped = new Uint8Array(rgba.length); // GL row 0 is the bottom row
    for (let r = 0; r < h; r++) {
      flipped.set(rgba.subarray((h - 1 - r) * w * 4, (h - r) * w * 4), r * w * 4);
    }
    let binary = '';
    for (let i = 0; i < flipped.length; i += 0x8000) {
      binary += String.fromCharCode.apply(null, flipped.subarray(i, i + 0x8000));
    }
    return { width: w, height: h, rgba: btoa(binary) };
  }

  // ------------------------------------------------------------------ motion

  const clamp = (v, r) => Math.max(-r, Math.min(r, v));

  // The authors' circle path (photo3d.render.paths): pose translation
  // t = (-0.015 cos(pi u), -0.015 sin(pi u), -0.05 cos(pi u / 2)), u in [-2, 2);
  // the camera position is -t.
  function circle(seconds) {
    const u = (seconds / LOOP_SECONDS * 4) % 4 - 2;
    return [RANGE[0] * Math.cos(Math.PI * u), RANGE[1] * Math.sin(Math.PI * u),
      RANGE[2] * Math.cos(Math.PI * u / 2)];
  }

  // Advance the camera by dt seconds; returns true while it still moves.
  function step(now, dt) {
    if (state.animate) { // exactly on the path (faded in), velocity kept for a hand-off
      if (state.animStart === null) state.animStart = now;
      const t = (now - state.animStart) / 1000;
      const ease = Math.min(1, t / 1.5);
      const smooth = ease * ease * (3 - 2 * ease);
      state.offset = circle(t).map((v) => v * smooth);
      for (let i = 0; i < 3; i++) {
        const next = state.rest[i] + state.offset[i];
        state.vel[i] = dt > 0 ? (next - state.pos[i]) / dt : 0;
        state.pos[i] = next;
      }
      return true;
    }
    // Critically damped spring towards rest + offset, solved exactly for any dt
    // (frames can be slow): x(t) = (x0 + (v0 + w x0) t) e^(-w t) about the target.
    let moving = false;
    const e = Math.exp(-SPRING * dt);
    for (let i = 0; i < 3; i++) {
      const target = state.rest[i] + state.offset[i];
      const x0 = state.pos[i] - target, v0 = state.vel[i];
      const c = v0 + SPRING * x0;
      const x = (x0 + c * dt) * e;
      state.vel[i] = (v0 - SPRING * c * dt) * e;
      // never beyond the range, even if the spring overshoots
      state.pos[i] = state.rest[i] + clamp(target + x - state.rest[i], RANGE[i]);
      if (Math.abs(x) > 1e-6 || Math.abs(state.vel[i]) > 1e-5) moving = true;
    }
    return moving;
  }

  function frame(now) {
    frameRequested = false;
    const dt = lastTime === null ? 0 : Math.min((now - lastTime) / 1000, 0.5);
    lastTime = now;
    const moving = step(now, dt);
    draw();
    if (moving) wake(); else lastTime = null;
  }

  function wake() {
    if (!frameRequested && gpu) {
      frameRequested = true;
      requestAnimationFrame(frame);
    }
  }

  // The user took over: stop the animation, keep the current motion.
  function interact(offset) {
    state.animate = false;
    state.pose = null;
    for (let i = 0; i < 3; i++) state.offset[i] = clamp(offset[i], RANGE[i]);
    wake();
  }

  function setAnimate(on) {
    state.animate = Boolean(on);
    state.animStart = null;
    if (!on) state.offset = [0, 0, 0];
    wake();
  }

  // Set the camera exactly (no spring, no range limit) and stop the animation:
  // [x, y, z] = camera position in the input camera's frame, or 16 numbers = a
  // row-major 4x4 camera-from-world pose (photo3d's Camera.pose).
  function setCamera(camera) {
    const values = Array.from(camera, Number);
    if (!(values.length === 3 || values.length === 16) || !values.every(Number.isFinite)) {
      throw new Error('setCamera needs 3 numbers (position) or 16 (row-major pose)');
    }
    state.animate = false;
    state.offset = [0, 0, 0];
    state.vel = [0, 0, 0];
    state.pose = values.length === 16 ? values : null;
    let position = values;
    if (state.pose) { // camera centre -R^T t of the pose [R t; 0 1]
      const p = state.pose;
      position = [0, 1, 2].map((i) => -(p[i] * p[3] + p[4 + i] * p[7] + p[8 + i] * p[11]));
    }
    state.rest = position.slice(0, 3);
    state.pos = position.slice(0, 3);
    if (gpu) draw();
  }

  function applyHash() {
    const params = new URLSearchParams(window.location.hash.slice(1));
    if (params.get('static') === '1') setAnimate(false);
    const camera = params.get('camera');
    if (camera) setCamera(camera.split(','));
  }

  function listen() {
    // Mouse: hovering tilts the view (pointer position in the canvas -> offset).
    // Touch and pen: dragging does, relative to where the finger went down.
    let drag = null;
    const size = () => canvas.getBoundingClientRect();
    const fromPosition = (event) => {
      const r = size();
      return [(2 * (event.clientX - r.left) / r.width - 1) * RANGE[0],
        (2 * (event.clientY - r.top) / r.height - 1) * RANGE[1], state.offset[2]];
    };
    canvas.addEventListener('pointerdown', (event) => {
      askOrientationPermission();
      if (event.pointerType !== 'mouse') {
        drag = { x: event.clientX, y: event.clientY, offset: state.offset.slice() };
        // keep receiving the drag outside the canvas (only real pointers can be captured)
        if (event.isTrusted) canvas.setPointerCapture(event.pointerId);
      }
    });
    canvas.addEventListener('pointermove', (event) => {
      if (event.pointerType === 'mouse') { interact(fromPosition(event)); return; }
      if (!drag) return;
      const half = Math.min(size().width, size().height) / 2;
      interact([drag.offset[0] + (event.clientX - drag.x) / half * RANGE[0],
        drag.offset[1] + (event.clientY - drag.y) / half * RANGE[1], drag.offset[2]]);
    });
    // Letting go (or the mouse leaving) springs the view back to the centre.
    const release = () => {
      drag = null;
      if (!state.animate) interact([0, 0, state.offset[2]]);
    };
    canvas.addEventListener('pointerup', (event) => {
      if (event.pointerType !== 'mouse') release();
    });
    canvas.addEventListener('pointercancel', release);
    canvas.addEventListener('pointerleave', (event) => {
      if (event.pointerType === 'mouse') release();
    });
    // Wheel: forward and back along the viewing direction.
    canvas.addEventListener('wheel', (event) => {
      event.preventDefault();
      const o = state.offset;
      interact([o[0], o[1], o[2] - event.deltaY * 0.0001]);
    }, { passive: false });
    // Device tilt (phones, tablets): relative to the first reading, which slowly
    // follows the device so a new holding angle becomes the new centre.
    let base = null;
    window.addEventListener('deviceorientation', (event) => {
      if (event.beta === null || event.gamma === null) return;
      let tx = event.gamma, ty = event.beta; // left-right, front-back tilt (degrees)
      const angle = (screen.orientation && screen.orientation.angle) || 0;
      if (angle === 90) [tx, ty] = [ty, -tx];
      else if (angle === 270 || angle === -90) [tx, ty] = [-ty, tx];
      else if (angle === 180) [tx, ty] = [-tx, -ty];
      if (!base) { base = [tx, ty]; return; }
      const follow = 0.002; // per event (about 60 a second): a time constant of ~8 s
      base = [base[0] + follow * (tx - base[0]), base[1] + follow * (ty - base[1])];
      const dx = (tx - base[0]) / TILT_DEGREES, dy = (ty - base[1]) / TILT_DEGREES;
      if (!state.animate || Math.hypot(dx, dy) > 0.15) {
        interact([dx * RANGE[0], dy * RANGE[1], state.offset[2]]);
      }
    });
    window.addEventListener('resize', () => { // resizing clears the canvas: redraw now
      resize();
      if (gpu) draw();
    });
    window.addEventListener('hashchange', applyHash);
    canvas.addEventListener('webglcontextlost', (event) => { event.preventDefault(); gpu = null; });
    canvas.addEventListener('webglcontextrestored', () => { upload(); wake(); });
  }

  let permissionAsked = false;
  function askOrientationPermission() { // iOS asks the user, only from a gesture
    const D = window.DeviceOrientationEvent;
    if (!permissionAsked && D && typeof D.requestPermission === 'function') {
      permissionAsked = true;
      // a refusal is the user's choice: the view then just ignores the tilt
      D.requestPermission().catch(() => {});
    }
  }

  // -------------------------------------------------------------------- main

  // True when WebGL runs on the CPU (SwiftShader, llvmpipe, ...): there 4x
  // multisampling doubles the time of every frame, so it is left off.
  function softwareRenderer() {
    const probe = document.createElement('canvas').getContext('webgl2');
    if (!probe) return false;
    const info = probe.getExtension('WEBGL_debug_renderer_info');
    const name = String(probe.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : probe.RENDERER));
    const lose = probe.getExtension('WEBGL_lose_context');
    if (lose) lose.loseContext();
    return /swiftshader|llvmpipe|softpipe|software|basic render/i.test(name);
  }

  async function main() {
    viewer.timings.scriptStartMs = performance.now(); // the page is parsed
    header = JSON.parse(document.getElementById('photo3d-header').textContent);
    gl = canvas.getContext('webgl2', { antialias: !softwareRenderer(), alpha: false, depth: true });
    if (!gl) {
      fail('This 3D photo needs WebGL 2, which this browser does not offer or has ' +
        'turned off. Open it in a current Chrome, Edge, Firefox or Safari.');
      return;
    }
    if (typeof DecompressionStream !== 'function') {
      fail('This 3D photo needs a browser from 2023 or later (DecompressionStream).');
      return;
    }
    // Reading one pixel waits until the GPU has finished what was asked before.
    const sync = () => gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
    try {
      mesh = await decode();
      const t0 = performance.now();
      resize();
      upload();
      sync();
      const t1 = performance.now();
      state.animate = header.animate !== false;
      applyHash();
      draw();
      sync();
      Object.assign(viewer.timings, { uploadMs: t1 - t0, drawMs: performance.now() - t1 });
    } catch (err) {
      fail('This 3D photo could not be shown', err);
      throw err;
    }
    viewer.firstFrameMs = performance.now(); // milliseconds since navigation start
    viewer.ready = true;
    listen();
    wake();
  }

  main();
})();
