// The rgbn web viewer (written by `rgbn publish`): WebGL2, plain JavaScript, no build step,
// no network access. It relights an RGBN image (colour + unit normal per pixel) from two Deep
// Zoom tile pyramids: albedo_files/K/C_R.png (sRGB, RGB or RGBA with the coverage in alpha)
// and normals_files/K/C_R.png (RGB8, (n+1)/2, OpenGL frame: +x right, +y up, +z to the
// viewer). It fetches only the tiles visible at the level matching the zoom, showing the
// level that fits one tile (always loaded) and finer levels already loaded until they arrive.
// Opened from disk (file://), where browsers refuse image files as textures, it takes the
// small levels from fallback/K.js (data: URLs) instead; `rgbn serve DIR` shows every level.
//
// URL parameters: light=X,Y,Z (one white light), view=relit|normals|specular_enhancement|
// curvature, exposure=EV, zoom=Z (screen pixels per image pixel), pan=X,Y (the image pixel at
// the top-left corner), bare (canvas only, image 1:1 at the top-left, no controls), fit (with
// bare: the image fitted to the window as without bare: 95 % of it, centred).
//
// The shaders implement rgbn's formulas (src/render/mod.rs `relight`, the issue-16 views):
//   relit:  2^ev · (albedo · (ambient + Σ cᵢ max(0, n·lᵢ)) + ks · Σ cᵢ max(0, n·hᵢ)^shininess),
//           specular only where n·lᵢ > 0, hᵢ = normalize(lᵢ + (0,0,1)); clamp, sRGB encode;
//           alpha = coverage, coverage 0 → transparent black.
//   normals: (n+1)/2 · 255, opaque.
//   specular_enhancement: 2^ev · Σ cᵢ (kd·max(0, n·lᵢ) + ks·max(0, n·hᵢ)^α) (lit side only),
//           grey, clamp, sRGB encode; alpha = coverage.
//   curvature: H = ½(∂nx/∂x + ∂ny/∂y) (y up, central differences, one-sided at borders and
//           next to pixels with coverage < 0.5), t = clamp(H·scale, −1, 1), red (t ≥ 0) or
//           blue with f = round((1 − |t|)·255); alpha = coverage.
(function () {
  'use strict';

  const VIEWS = ['relit', 'normals', 'specular_enhancement', 'curvature'];
  const MAX_LIGHTS = 8;
  const $ = (id) => document.getElementById(id);
  const statusEl = $('status');
  const messages = [];

  const notes = [];

  function fail(msg) {
    if (messages.includes(msg)) return;
    messages.push(msg);
    statusEl.textContent = messages.concat(notes).join('\n');
    document.title = 'rgbn viewer: error: ' + msg;
    console.error('rgbn viewer: ' + msg);
  }

  // A message that is not an error (the page still becomes ready).
  function note(msg) {
    if (notes.includes(msg)) return;
    notes.push(msg);
    statusEl.textContent = messages.concat(notes).join('\n');
    console.warn('rgbn viewer: ' + msg);
  }

  let meta;
  try {
    meta = JSON.parse($('rgbn-meta').textContent);
  } catch (e) {
    fail('this page holds no image metadata (was it written by rgbn publish?)');
    return;
  }

  // ---- state, from the metadata and the URL ----
  const q = new URLSearchParams(location.search);
  const bare = q.has('bare');
  const numbers = (s, n) => {
    const v = s.split(',').map((t) => Number(t.trim()));
    return v.length === n && v.every(Number.isFinite) ? v : null;
  };
  const state = {
    view: VIEWS.includes(meta.view) ? meta.view : 'relit',
    lights: meta.shading.lights.map((l) => ({ dir: l.direction.slice(), color: l.color.slice() })),
    exposure: meta.shading.exposure_ev,
    zoom: 1,
    panX: 0,
    panY: 0,
  };
  if (q.has('light')) {
    const v = numbers(q.get('light'), 3);
    if (v && (v[0] || v[1] || v[2])) state.lights = [{ dir: v, color: [1, 1, 1] }];
    else fail('light=' + q.get('light') + ': expected X,Y,Z (three numbers, not all 0)');
  }
  if (q.has('view')) {
    const v = q.get('view');
    if (VIEWS.includes(v)) state.view = v;
    else fail('view=' + v + ': unknown view (' + VIEWS.join(', ') + ')');
  }
  if (q.has('exposure')) {
    const e = Number(q.get('exposure'));
    if (Number.isFinite(e)) state.exposure = e;
    else fail('exposure=' + q.get('exposure') + ': not a number');
  }
  let fitPending = !bare || q.has('fit');
  // Fit again when the window changes size, until the user zooms or pans.
  let autoFit = fitPending;
  if (q.has('zoom')) {
    const z = Number(q.get('zoom'));
    if (Number.isFinite(z) && z > 0) {
      state.zoom = z;
      fitPending = false;
      autoFit = false;
    } else fail('zoom=' + q.get('zoom') + ': expected a number > 0');
  }
  if (q.has('pan')) {
    const v = numbers(q.get('pan'), 2);
    if (v) {
      [state.panX, state.panY] = v;
      fitPending = false;
      autoFit = false;
    } else fail('pan=' + q.get('pan') + ': expected X,Y');
  }
  if (bare) document.body.classList.add('bare');

  // ---- WebGL ----
  const canvas = $('gl');
  const gl = canvas.getContext('webgl2', {
    alpha: true,
    premultipliedAlpha: false,
    antialias: false,
    depth: false,
    preserveDrawingBuffer: true,
  });
  if (!gl) {
    fail('WebGL2 is not available in this browser');
    return;
  }

  const VS = `#version 300 es
uniform vec2 u_canvas;
uniform vec4 u_rect; // x0, y0, x1, y1 in canvas pixels, y down
void main() {
  vec2 c = vec2((gl_VertexID & 1) == 1 ? u_rect.z : u_rect.x,
                (gl_VertexID & 2) == 2 ? u_rect.w : u_rect.y);
  gl_Position = vec4(c.x / u_canvas.x * 2.0 - 1.0, 1.0 - c.y / u_canvas.y * 2.0, 0.0, 1.0);
}`;

  const FS = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
uniform sampler2D u_albedo;   // SRGB8_ALPHA8: fetches are linear colour, alpha = coverage
uniform sampler2D u_normals;  // RGBA8: (n+1)/2
uniform vec2 u_canvas;        // canvas size in pixels
uniform vec2 u_origin;        // canvas position (y down) of the tile's top-left corner
uniform float u_scale;        // canvas pixels per texel
uniform ivec2 u_size;         // tile size in texels
uniform int u_view;           // 0 relit, 1 normals, 2 specular enhancement, 3 curvature
uniform int u_nlights;
uniform vec3 u_ldir[${MAX_LIGHTS}];   // unit, towards the light
uniform vec3 u_lhalf[${MAX_LIGHTS}];  // normalize(l + (0,0,1))
uniform vec3 u_lcol[${MAX_LIGHTS}];
uniform float u_ambient;
uniform float u_ks;
uniform float u_shininess;
uniform float u_gain;         // 2^exposure
uniform vec3 u_se;            // specular enhancement kd, ks, alpha
uniform float u_curv;         // curvature scale per texel of this level
out vec4 o;

vec3 normalAt(ivec2 p) {
  vec3 v = texelFetch(u_normals, clamp(p, ivec2(0), u_size - 1), 0).rgb * 2.0 - 1.0;
  float l = length(v);
  return l > 0.0 ? v / l : vec3(0.0, 0.0, 1.0);
}
bool inside(ivec2 p) {
  return p.x >= 0 && p.y >= 0 && p.x < u_size.x && p.y < u_size.y
    && texelFetch(u_albedo, p, 0).a >= 0.5;
}
float diffAxis(float c, bool hasBefore, float before, bool hasAfter, float after) {
  if (hasBefore && hasAfter) return (after - before) * 0.5;
  if (hasAfter) return after - c;
  if (hasBefore) return c - before;
  return 0.0;
}
float srgb(float c) {
  return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}
vec3 srgb8(vec3 v) {
  v = clamp(v, 0.0, 1.0);
  return floor(vec3(srgb(v.r), srgb(v.g), srgb(v.b)) * 255.0 + 0.5) / 255.0;
}
float powUnit(float x, float s) { return pow(max(x, 1e-30), s); }

void main() {
  vec2 cpx = vec2(gl_FragCoord.x, u_canvas.y - gl_FragCoord.y);
  ivec2 p = clamp(ivec2(floor((cpx - u_origin) / u_scale)), ivec2(0), u_size - 1);
  vec4 a = texelFetch(u_albedo, p, 0);
  vec3 n = normalAt(p);
  if (u_view == 1) {
    o = vec4(floor((n + 1.0) * 127.5 + 0.5) / 255.0, 1.0);
    return;
  }
  if (u_view == 3) {
    ivec2 l = p - ivec2(1, 0), r = p + ivec2(1, 0);
    ivec2 up = p - ivec2(0, 1), down = p + ivec2(0, 1); // rows go down, y goes up
    float dx = diffAxis(n.x, inside(l), normalAt(l).x, inside(r), normalAt(r).x);
    float dy = diffAxis(n.y, inside(down), normalAt(down).y, inside(up), normalAt(up).y);
    float t = clamp(0.5 * (dx + dy) * u_curv, -1.0, 1.0);
    float f = floor((1.0 - abs(t)) * 255.0 + 0.5) / 255.0;
    o = vec4(t >= 0.0 ? vec3(1.0, f, f) : vec3(f, f, 1.0), a.a);
    return;
  }
  if (a.a <= 0.0) {
    o = vec4(0.0);
    return;
  }
  vec3 diff = vec3(u_ambient), spec = vec3(0.0), se = vec3(0.0);
  for (int i = 0; i < ${MAX_LIGHTS}; i++) {
    if (i >= u_nlights) break;
    float ndl = dot(n, u_ldir[i]);
    if (ndl > 0.0) {
      float ndh = clamp(dot(n, u_lhalf[i]), 0.0, 1.0);
      diff += u_lcol[i] * ndl;
      spec += u_lcol[i] * powUnit(ndh, u_shininess);
      se += u_lcol[i] * (u_se.x * ndl + u_se.y * powUnit(ndh, u_se.z));
    }
  }
  vec3 v = u_view == 2 ? u_gain * se : u_gain * (a.rgb * diff + u_ks * spec);
  o = vec4(srgb8(v), a.a);
}`;

  function compile(type, src) {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) {
      throw new Error('shader: ' + gl.getShaderInfoLog(s));
    }
    return s;
  }
  let prog;
  try {
    prog = gl.createProgram();
    gl.attachShader(prog, compile(gl.VERTEX_SHADER, VS));
    gl.attachShader(prog, compile(gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) {
      throw new Error('link: ' + gl.getProgramInfoLog(prog));
    }
  } catch (e) {
    fail(e.message);
    return;
  }
  const U = {};
  for (const name of ['u_albedo', 'u_normals', 'u_canvas', 'u_rect', 'u_origin', 'u_scale',
    'u_size', 'u_view', 'u_nlights', 'u_ldir', 'u_lhalf', 'u_lcol', 'u_ambient', 'u_ks',
    'u_shininess', 'u_gain', 'u_se', 'u_curv']) {
    U[name] = gl.getUniformLocation(prog, name);
  }
  gl.bindVertexArray(gl.createVertexArray());

  // ---- tiles ----
  // Deep Zoom levels (rgbn.json "tiles"): level K is ceil(size / 2^(max−K)); tiles of T² pixels,
  // each grown by O pixels into its neighbours; files LAYER_files/K/C_R.png.
  const T = meta.tiles.tile_size;
  const O = meta.tiles.overlap;
  const levelSize = meta.tiles.levels; // [[w, h]], level 0 (one pixel) first
  const maxLevel = levelSize.length - 1;
  // The finest level that fits in one tile: always loaded, shown while finer tiles arrive.
  let baseLevel = 0;
  for (let k = 0; k <= maxLevel; k++) {
    if (levelSize[k][0] <= T && levelSize[k][1] <= T) baseLevel = k;
  }
  const fallbackLevels = new Set(meta.tiles.fallback_levels);
  // From file:// the browser refuses image files as textures: only the levels with a
  // fallback script (data: URLs) can be shown.
  let fallbackMode = false;
  const MAX_TILES = 192; // tiles kept on the GPU (least recently drawn go first)
  const tiles = new Map(); // "K/C/R" → { ready, albedo, normals, w, h, used }
  let frame = 0;
  const stats = { requested: 0 }; // tile images requested (albedo and normals count one each)
  window.rgbnStats = stats;

  function upload(img, internalFormat) {
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
    try {
      gl.texImage2D(gl.TEXTURE_2D, 0, internalFormat, gl.RGBA, gl.UNSIGNED_BYTE, img);
    } catch (e) {
      gl.deleteTexture(tex);
      throw e;
    }
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    return tex;
  }

  function dropTile(key) {
    const t = tiles.get(key);
    if (t && t.albedo) gl.deleteTexture(t.albedo);
    if (t && t.normals) gl.deleteTexture(t.normals);
    tiles.delete(key);
  }

  // Switches to the fallback scripts: every tile is requested again from them.
  function enterFallback() {
    if (fallbackMode) return;
    fallbackMode = true;
    for (const key of Array.from(tiles.keys())) dropTile(key);
    // Only when the finest levels are missing from the fallback scripts.
    if (!fallbackLevels.has(maxLevel)) {
      note('opened from disk: showing up to ' + fallbackSide() + ' px; for every level run ' +
        '`rgbn serve` on this folder (or put it on any web server)');
    }
    requestDraw();
  }
  function fallbackSide() {
    let side = 0;
    for (const k of fallbackLevels) side = Math.max(side, levelSize[k][0], levelSize[k][1]);
    return side;
  }

  function loadTile(K, c, r) {
    const key = K + '/' + c + '/' + r;
    if (tiles.has(key)) return;
    const t = { ready: false, albedo: null, normals: null, w: 0, h: 0, used: frame };
    tiles.set(key, t);
    let pending = 2;
    for (const [what, format] of [['albedo', gl.SRGB8_ALPHA8], ['normals', gl.RGBA8]]) {
      const img = new Image();
      img.onload = () => {
        if (tiles.get(key) !== t) return; // dropped meanwhile
        try {
          t[what] = upload(img, format);
        } catch (e) {
          if (!fallbackMode && fallbackLevels.size) {
            enterFallback();
          } else {
            fail('the browser refused ' + img.src + ' as a texture (' + e.message + '); ' +
              'run `rgbn serve` on this folder and open the address it prints');
          }
          return;
        }
        t.w = img.naturalWidth;
        t.h = img.naturalHeight;
        if (--pending === 0) {
          t.ready = true;
          requestDraw();
        }
      };
      img.onerror = () => fail('cannot load ' + img.src);
      stats.requested++;
      if (fallbackMode) {
        fallbackUrl(K, what + '/' + c + '_' + r, (url) => { img.src = url; });
      } else {
        img.src = what + '_files/' + K + '/' + c + '_' + r + '.png';
      }
    }
  }

  // fallback/K.js calls rgbnFallback(K, {"albedo/C_R": "data:image/png;base64,…", …}).
  const fallbackData = new Map(); // K → { urls, waiting: [[name, k]] }
  window.rgbnFallback = (K, urls) => {
    const f = fallbackData.get(K);
    if (!f) return;
    f.urls = urls;
    for (const [name, k] of f.waiting) give(K, f, name, k);
    f.waiting = [];
  };
  function give(K, f, name, k) {
    if (name in f.urls) k(f.urls[name]);
    else fail('fallback/' + K + '.js has no tile ' + name);
  }
  function fallbackUrl(K, name, k) {
    let f = fallbackData.get(K);
    if (!f) {
      f = { urls: null, waiting: [] };
      fallbackData.set(K, f);
      const s = document.createElement('script');
      s.src = 'fallback/' + K + '.js';
      s.onerror = () => fail('cannot load ' + s.src);
      document.head.appendChild(s);
    }
    if (f.urls) give(K, f, name, k);
    else f.waiting.push([name, k]);
  }

  // Keeps at most MAX_TILES tiles: the least recently drawn go (never the base level's).
  function evict() {
    if (tiles.size <= MAX_TILES) return;
    const old = Array.from(tiles.entries())
      .filter(([key, t]) => t.used < frame && !key.startsWith(baseLevel + '/'))
      .sort((a, b) => a[1].used - b[1].used);
    for (let i = 0; i < old.length && tiles.size > MAX_TILES; i++) dropTile(old[i][0]);
  }

  // ---- drawing ----
  // The level whose pixels are at least as small as the screen's: level-0 pixels per screen
  // pixel 2^L ≤ 1/zoom, so a level pixel never covers more than one screen pixel.
  function levelFor(zoom) {
    const L = Math.floor(Math.log2(1 / zoom) + 1e-9);
    let K = Math.max(baseLevel, Math.min(maxLevel, maxLevel - L));
    if (fallbackMode) {
      while (K > baseLevel && !fallbackLevels.has(K)) K--;
    }
    return K;
  }

  function resize() {
    const dpr = bare ? 1 : window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr));
    const h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) {
      canvas.width = w;
      canvas.height = h;
    }
  }

  function fit() {
    resize();
    const z = 0.95 * Math.min(canvas.width / meta.width, canvas.height / meta.height);
    state.zoom = z;
    state.panX = (meta.width - canvas.width / z) / 2;
    state.panY = (meta.height - canvas.height / z) / 2;
  }

  function normalize(v) {
    const l = Math.hypot(v[0], v[1], v[2]);
    return [v[0] / l, v[1] / l, v[2] / l];
  }

  function setUniforms() {
    const W = canvas.width;
    const H = canvas.height;
    gl.uniform2f(U.u_canvas, W, H);
    gl.uniform1i(U.u_albedo, 0);
    gl.uniform1i(U.u_normals, 1);
    gl.uniform1i(U.u_view, VIEWS.indexOf(state.view));
    const n = Math.min(MAX_LIGHTS, state.lights.length);
    const dir = new Float32Array(3 * MAX_LIGHTS);
    const half = new Float32Array(3 * MAX_LIGHTS);
    const col = new Float32Array(3 * MAX_LIGHTS);
    for (let i = 0; i < n; i++) {
      const d = normalize(state.lights[i].dir);
      const h = normalize([d[0], d[1], d[2] + 1]);
      dir.set(d, 3 * i);
      half.set(h, 3 * i);
      col.set(state.lights[i].color, 3 * i);
    }
    gl.uniform1i(U.u_nlights, n);
    gl.uniform3fv(U.u_ldir, dir);
    gl.uniform3fv(U.u_lhalf, half);
    gl.uniform3fv(U.u_lcol, col);
    gl.uniform1f(U.u_ambient, meta.shading.ambient);
    gl.uniform1f(U.u_ks, meta.shading.specular);
    gl.uniform1f(U.u_shininess, meta.shading.shininess);
    gl.uniform1f(U.u_gain, Math.pow(2, state.exposure));
    const se = meta.specular_enhancement;
    gl.uniform3f(U.u_se, se.kd, se.ks, se.alpha);
  }

  // Draws the tiles of level K that overlap the canvas; `request`: load the missing ones.
  // Returns how many were missing.
  function drawLevel(K, W, H, request) {
    const [lw, lh] = levelSize[K];
    const f = Math.pow(2, maxLevel - K); // level-0 pixels per level-K pixel
    const s = state.zoom * f; // canvas pixels per level-K pixel
    gl.uniform1f(U.u_scale, s);
    gl.uniform1f(U.u_curv, meta.curvature_scale / f);
    // The tiles the canvas overlaps.
    const c0 = Math.max(0, Math.floor(state.panX / f / T));
    const r0 = Math.max(0, Math.floor(state.panY / f / T));
    const c1 = Math.min(Math.ceil(lw / T), Math.ceil((state.panX + W / state.zoom) / f / T));
    const r1 = Math.min(Math.ceil(lh / T), Math.ceil((state.panY + H / state.zoom) / f / T));
    let missing = 0;
    for (let r = r0; r < r1; r++) {
      for (let c = c0; c < c1; c++) {
        const t = tiles.get(K + '/' + c + '/' + r);
        if (!t || !t.ready) {
          missing++;
          if (request) loadTile(K, c, r);
          continue;
        }
        t.used = frame;
        // The tile's own pixels (its overlap is drawn by its neighbours) …
        const x0 = (c * T * f - state.panX) * state.zoom;
        const y0 = (r * T * f - state.panY) * state.zoom;
        const x1 = x0 + Math.min(T, lw - c * T) * s;
        const y1 = y0 + Math.min(T, lh - r * T) * s;
        // … and where its texture starts (O pixels earlier inside the level).
        const ox = c > 0 ? O : 0;
        const oy = r > 0 ? O : 0;
        gl.activeTexture(gl.TEXTURE0);
        gl.bindTexture(gl.TEXTURE_2D, t.albedo);
        gl.activeTexture(gl.TEXTURE1);
        gl.bindTexture(gl.TEXTURE_2D, t.normals);
        gl.uniform2f(U.u_origin, x0 - ox * s, y0 - oy * s);
        gl.uniform2i(U.u_size, t.w, t.h);
        gl.uniform4f(U.u_rect, x0, y0, x1, y1);
        gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
      }
    }
    return missing;
  }

  function draw() {
    if (fitPending) {
      fit();
      fitPending = false;
    }
    resize();
    frame++;
    const W = canvas.width;
    const H = canvas.height;
    gl.viewport(0, 0, W, H);
    gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.useProgram(prog);
    setUniforms();
    const target = levelFor(state.zoom);
    // The base level (always loaded), then finer levels already loaded, then the target level,
    // whose missing visible tiles are requested: the coarser picture shows until they arrive.
    drawLevel(baseLevel, W, H, true);
    for (let K = baseLevel + 1; K < target; K++) drawLevel(K, W, H, false);
    const missing = target > baseLevel ? drawLevel(target, W, H, true) : 0;
    evict();
    if (missing === 0 && messages.length === 0) document.title = 'rgbn viewer: ready';
    updateUi();
  }

  let frameRequested = false;
  function requestDraw() {
    if (frameRequested) return;
    frameRequested = true;
    requestAnimationFrame(() => {
      frameRequested = false;
      draw();
    });
  }

  // ---- controls ----
  const viewSel = $('view');
  const expo = $('exposure');
  const pad = $('lightpad');

  function lightFromDisc(x, y) {
    let r = Math.hypot(x, y);
    if (r > 0.999) {
      x *= 0.999 / r;
      y *= 0.999 / r;
      r = 0.999;
    }
    const color = state.lights.length ? state.lights[0].color : [1, 1, 1];
    const l = { dir: [x, y, Math.sqrt(1 - r * r)], color };
    if (state.lights.length) state.lights[0] = l;
    else state.lights.push(l);
    requestDraw();
  }

  function updateUrl() {
    if (bare) return;
    const p = new URLSearchParams(location.search);
    const d = normalize(state.lights[0] ? state.lights[0].dir : [0, 0, 1]);
    p.set('light', d.map((v) => v.toFixed(3)).join(','));
    p.set('view', state.view);
    p.set('exposure', state.exposure.toFixed(2));
    try {
      history.replaceState(null, '', '?' + p.toString());
    } catch (e) {
      // file:// pages may refuse; the URL is a convenience only.
    }
  }

  function updateUi() {
    if (bare) return;
    viewSel.value = state.view;
    expo.value = String(state.exposure);
    $('ev').textContent = (state.exposure >= 0 ? '+' : '') + state.exposure.toFixed(2) + ' EV';
    const d = state.lights.length ? normalize(state.lights[0].dir) : [0, 0, 1];
    $('lighttext').textContent = 'light ' + d.map((v) => v.toFixed(2)).join(', ') +
      (state.lights.length > 1 ? ' (+' + (state.lights.length - 1) + ' more)' : '');
    let legend = meta.width + '×' + meta.height + ' px · zoom ' + state.zoom.toFixed(3);
    if (state.view === 'curvature') {
      legend += '\nmean curvature, scale ' + meta.curvature_scale.toPrecision(4) +
        ' px: red convex, white flat, blue concave (saturates at |H| = ' +
        (1 / meta.curvature_scale).toPrecision(3) + ' /px)';
    }
    $('legend').textContent = legend;
    const ctx = pad.getContext('2d');
    const R = pad.width / 2;
    ctx.clearRect(0, 0, pad.width, pad.height);
    ctx.strokeStyle = '#666';
    ctx.beginPath();
    ctx.arc(R, R, R - 1, 0, 2 * Math.PI);
    ctx.stroke();
    ctx.fillStyle = '#fd4';
    ctx.beginPath();
    ctx.arc(R + d[0] * (R - 4), R - d[1] * (R - 4), 4, 0, 2 * Math.PI);
    ctx.fill();
  }

  // RTIViewer's specular enhancement controls under its names: "Diffuse color" (kd),
  // "Specularity" (ks), "Highlight size" (the exponent α), shown with that view only.
  const seBox = $('se-controls');
  const seInputs = [['se-kd', 'kd'], ['se-ks', 'ks'], ['se-alpha', 'alpha']];
  function showSe() {
    if (seBox) seBox.style.display = state.view === 'specular_enhancement' ? '' : 'none';
  }
  if (!bare && seBox) {
    for (const [id, key] of seInputs) {
      const el = $(id);
      el.value = String(meta.specular_enhancement[key]);
      el.addEventListener('input', () => {
        meta.specular_enhancement[key] = Number(el.value);
        requestDraw();
      });
    }
    showSe();
  }

  if (!bare) {
    viewSel.addEventListener('change', () => {
      state.view = viewSel.value;
      showSe();
      updateUrl();
      requestDraw();
    });
    expo.addEventListener('input', () => {
      state.exposure = Number(expo.value);
      updateUrl();
      requestDraw();
    });
    $('fit').addEventListener('click', () => {
      autoFit = true;
      fit();
      requestDraw();
    });
    const padDrag = (e) => {
      const b = pad.getBoundingClientRect();
      const R = b.width / 2;
      lightFromDisc((e.clientX - b.left - R) / R, -(e.clientY - b.top - R) / R);
    };
    pad.addEventListener('pointerdown', (e) => {
      pad.setPointerCapture(e.pointerId);
      padDrag(e);
    });
    pad.addEventListener('pointermove', (e) => {
      if (e.buttons & 1) padDrag(e);
    });
    pad.addEventListener('pointerup', updateUrl);

    let drag = null;
    canvas.addEventListener('pointerdown', (e) => {
      canvas.setPointerCapture(e.pointerId);
      drag = { x: e.clientX, y: e.clientY };
      if (e.shiftKey) shiftLight(e);
    });
    const shiftLight = (e) => {
      const b = canvas.getBoundingClientRect();
      const R = Math.min(b.width, b.height) / 2;
      lightFromDisc((e.clientX - b.left - b.width / 2) / R, -(e.clientY - b.top - b.height / 2) / R);
    };
    canvas.addEventListener('pointermove', (e) => {
      if (!drag) return;
      if (e.shiftKey) {
        shiftLight(e);
      } else {
        const dpr = window.devicePixelRatio || 1;
        autoFit = false;
        state.panX -= ((e.clientX - drag.x) * dpr) / state.zoom;
        state.panY -= ((e.clientY - drag.y) * dpr) / state.zoom;
        requestDraw();
      }
      drag = { x: e.clientX, y: e.clientY };
    });
    const endDrag = () => {
      if (drag) updateUrl();
      drag = null;
    };
    canvas.addEventListener('pointerup', endDrag);
    canvas.addEventListener('pointercancel', endDrag);
    canvas.addEventListener('wheel', (e) => {
      e.preventDefault();
      const b = canvas.getBoundingClientRect();
      const dpr = window.devicePixelRatio || 1;
      const cx = (e.clientX - b.left) * dpr;
      const cy = (e.clientY - b.top) * dpr;
      const ix = state.panX + cx / state.zoom;
      const iy = state.panY + cy / state.zoom;
      const unit = e.deltaMode === 1 ? 40 : e.deltaMode === 2 ? 800 : 1;
      const z = Math.min(64, Math.max(1e-3, state.zoom * Math.exp(-e.deltaY * unit * 0.002)));
      autoFit = false;
      state.zoom = z;
      state.panX = ix - cx / z;
      state.panY = iy - cy / z;
      requestDraw();
    }, { passive: false });
  }
  // Also in bare mode: headless browsers may size the window after the first layout.
  window.addEventListener('resize', () => {
    fitPending = autoFit;
    draw();
  });

  draw();
})();
