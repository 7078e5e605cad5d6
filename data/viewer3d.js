/* The viewer's 3D lobe and sky (issue 37), inserted into data/viewer.html
 * after SB_DATA by sb_viewer_write.  Both run the page's one program: the
 * lobe is f(L, V) for the chosen light L over a grid of view directions
 * (u_shape 3), the sky a fixed quadrature of a procedural environment
 * (u_env 1).  tests/test_view3d.c repeats both on the CPU. */

const LOBE_N = 48; /* the lobe's grid: theta_o rows x phi_o columns */
const SLICE_N = 16; /* a slice's SLICE_N^2 samples, theta_o from -90 to 90 degrees */
const SKY_NT = 12, SKY_NP = 24; /* the sky's quadrature: cell centres in theta (0..pi) x phi */

/* GLSL for the scene, after sb_lit.  The sky: a gradient from a warm
 * horizon to a blue zenith, a dim ground, and a soft sun towards u_light
 * (the light the user drags); the sphere sums f cos theta_i sky dw over
 * the cell centres of an SKY_NT x SKY_NP grid of the sphere of directions. */
const VIEW3D_GLSL = `
const float SB_VIEW_PI = 3.14159265358979;
vec3 sb_sky(vec3 d) {
  vec3 s = d.z > 0.0 ? mix(vec3(1.0, 0.9, 0.75), vec3(0.25, 0.45, 1.0), d.z) : vec3(0.25, 0.22, 0.2);
  return 0.4 * s + 3.0 * vec3(1.0, 0.95, 0.85) * pow(max(dot(d, u_light), 0.0), 8.0);
}
uniform int u_sky_hdr;      // 1: the cell's mean of a dropped HDR (u_sky, SKY_NP x SKY_NT) for sb_sky
uniform sampler2D u_sky;
vec3 sb_sky_radiance(int which, vec3 t, vec3 b, vec3 n, vec3 V) {
  vec3 sum = vec3(0.0);
  for (int i = 0; i < ${SKY_NT}; i++) {
    float th = (float(i) + 0.5) * SB_VIEW_PI / ${SKY_NT}.0;
    for (int j = 0; j < ${SKY_NP}; j++) {
      float ph = (float(j) + 0.5) * 2.0 * SB_VIEW_PI / ${SKY_NP}.0;
      vec3 d = vec3(sin(th) * cos(ph), sin(th) * sin(ph), cos(th));
      vec3 e = u_sky_hdr == 1 ? texelFetch(u_sky, ivec2(j, i), 0).rgb : sb_sky(d);
      if (dot(d, n) > 0.0) sum += sb_lit(which, vec3(dot(d, t), dot(d, b), dot(d, n)), V) * e * sin(th);
    }
  }
  return sum * (SB_VIEW_PI / ${SKY_NT}.0) * (2.0 * SB_VIEW_PI / ${SKY_NP}.0);
}
// the lobe's cell q (pixels): theta_o = (row + 1/2) / n pi/2, phi_o = (column + 1/2) / n 2 pi
vec4 sb_lobe_cell(vec2 q) {
  vec2 a = q / u_size * vec2(2.0 * SB_VIEW_PI, 0.5 * SB_VIEW_PI);
  vec3 V = vec3(sin(a.y) * cos(a.x), sin(a.y) * sin(a.x), cos(a.y));
  if (!(u_light.z > 0.0)) return vec4(0.0, 0.0, 0.0, 1.0);
  return vec4(u_mode == 0 ? sb_original(u_light, V) : sb_brdf(u_light, V), 1.0);
}
// a slice (u_shape 4): sample k = row n + column, signed theta_o = ((k + 1/2) / n^2 2 - 1) pi/2 in the
// plane of azimuth u_slice_phi (for theta_o > 0; the light's mirror side when it is the light's azimuth + pi)
uniform float u_slice_phi;
vec4 sb_slice_cell(vec2 q) {
  float k = floor(q.y) * u_size + floor(q.x), to = ((k + 0.5) / (u_size * u_size) * 2.0 - 1.0) * 0.5 * SB_VIEW_PI;
  vec3 V = vec3(sin(to) * cos(u_slice_phi), sin(to) * sin(u_slice_phi), cos(to));
  if (!(u_light.z > 0.0)) return vec4(0.0, 0.0, 0.0, 1.0);
  return vec4(u_mode == 0 ? sb_original(u_light, V) : sb_brdf(u_light, V), 1.0);
}
`;

/* An RGBA32F target of n x n, made once per size; null where the browser
 * cannot render to float. */
const floatTargets = {};
function floatTarget(gl, n) {
  if (floatTargets[n] !== undefined) return floatTargets[n];
  const fb = gl.getExtension('EXT_color_buffer_float') ? gl.createFramebuffer() : null;
  if (fb) {
    const rb = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, rb);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.RGBA32F, n, n);
    gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, rb);
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) throw new Error('RGBA32F framebuffer incomplete');
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  }
  return (floatTargets[n] = fb);
}

/* f(S.light, V) RGBA over an n x n grid, rows from the bottom: shape 3
 * the lobe, 4 a slice; mode 0 original, 1 reconstruction (J terms as
 * set); null without float targets. */
function fGrid(gl, R, mode, shape, n) {
  const fb = floatTarget(gl, n);
  if (!fb) return null;
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  const L = S.light;
  gl.uniform1f(R.U('u_slice_phi'), Math.atan2(L[1], L[0]) + Math.PI + (S.slicePsi * Math.PI) / 180);
  R.panel(mode, 0, 0, n, true, shape);
  const px = new Float32Array(n * n * 4);
  gl.readPixels(0, 0, n, n, gl.RGBA, gl.FLOAT, px);
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  return px;
}
const lobeGrid = (gl, R, mode) => fGrid(gl, R, mode, 3, LOBE_N);
const sliceGrid = (gl, R, mode) => fGrid(gl, R, mode, 4, SLICE_N);

/* test mode, ?lobe=1 and ?slice=1 (&psi=DEG): the grids as lines
 * lobe_rec=, lobe_orig=, slice_rec=, slice_orig= */
function lobeTest(gl, R, lines) {
  const modes = D.ref ? [['rec', 1], ['orig', 0]] : [['rec', 1]];
  for (const [what, grid] of [['lobe', lobeGrid], ['slice', sliceGrid]]) {
    if (Q.get(what) !== '1') continue;
    for (const [key, mode] of modes) {
      const px = grid(gl, R, mode);
      if (!px) throw new Error('no float render target for the ' + what);
      lines.push(what + '_' + key + '=' + bytesB64(px));
    }
  }
}

/* ---- drawing the lobe: radius = luminance, a wire mesh, drag to turn --- */

const lobeView = { yaw: -0.6, pitch: 0.35 };

function lobeProject(p, W, H, R) {
  const [cy, sy, cp, sp] = [Math.cos(lobeView.yaw), Math.sin(lobeView.yaw), Math.cos(lobeView.pitch), Math.sin(lobeView.pitch)];
  const x = cy * p[0] - sy * p[1], y = sy * p[0] + cy * p[1];
  return [W / 2 + R * x, H * 0.72 - R * (cp * p[2] - sp * y)];
}

function lobePoints(px, peak) {
  const pts = [], n = LOBE_N;
  for (let i = 0; i < n; i++)
    for (let j = 0; j < n; j++) {
      const k = (i * n + j) * 4, v = 0.2126 * px[k] + 0.7152 * px[k + 1] + 0.0722 * px[k + 2];
      const r = S.log ? Math.max(0, Math.log10(Math.max(v, 1e-30) / peak) / 4 + 1) : Math.max(v, 0) / peak;
      const th = ((i + 0.5) / n) * 0.5 * Math.PI, ph = ((j + 0.5) / n) * 2 * Math.PI;
      pts.push([r * Math.sin(th) * Math.cos(ph), r * Math.sin(th) * Math.sin(ph), r * Math.cos(th)]);
    }
  return pts;
}

function lobeMesh(x, pts, colour, W, H, R) {
  const n = LOBE_N, at = (i, j) => lobeProject(pts[i * n + (j % n)], W, H, R);
  x.strokeStyle = colour;
  x.beginPath();
  for (let i = 1; i < n; i += 4)
    for (let j = 0; j <= n; j++) (j ? x.lineTo : x.moveTo).apply(x, at(i, j));
  for (let j = 0; j < n; j += 3)
    for (let i = 0; i < n; i++) (i ? x.lineTo : x.moveTo).apply(x, at(i, j));
  x.stroke();
}

function drawLobe(gl, R) {
  const c = $('lobe'), x = c.getContext('2d'), W = c.width, H = c.height, Rp = Math.min(W, H) * 0.42;
  x.fillStyle = '#111';
  x.fillRect(0, 0, W, H);
  x.fillStyle = '#888';
  const rec = lobeGrid(gl, R, 1), orig = D.ref ? lobeGrid(gl, R, 0) : null;
  if (!rec) return void x.fillText('no float render target: no lobe', 10, 20);
  let peak = 0;
  for (const px of orig ? [rec, orig] : [rec])
    for (let k = 0; k < px.length; k += 4) peak = Math.max(peak, 0.2126 * px[k] + 0.7152 * px[k + 1] + 0.0722 * px[k + 2]);
  x.fillText('f(light, view), ' + (S.log ? 'log, 4 decades' : 'linear') + '; drag to turn', 6, 14);
  x.strokeStyle = '#444';
  x.beginPath();
  for (let a = 0; a <= 64; a++) (a ? x.lineTo : x.moveTo).apply(x, lobeProject([Math.cos(a / 10.186), Math.sin(a / 10.186), 0], W, H, Rp));
  x.stroke();
  const L = S.light, M = [-L[0], -L[1], L[2]];
  [[L, '#ffd54f'], [M, '#666']].forEach(([d, col]) => {
    x.strokeStyle = col;
    x.beginPath();
    x.moveTo.apply(x, lobeProject([0, 0, 0], W, H, Rp));
    x.lineTo.apply(x, lobeProject(d, W, H, Rp));
    x.stroke();
  });
  if (!(peak > 0) || !(L[2] > 0)) return;
  if (orig) lobeMesh(x, lobePoints(orig, peak), 'rgba(255,255,255,0.55)', W, H, Rp);
  lobeMesh(x, lobePoints(rec, peak), curveColour(S.terms), W, H, Rp);
}

function bindLobe(redraw) {
  const c = $('lobe');
  let last = null;
  c.addEventListener('pointerdown', (e) => { c.setPointerCapture(e.pointerId); last = [e.clientX, e.clientY]; });
  c.addEventListener('pointermove', (e) => {
    if (!(e.buttons & 1) || !last) return;
    lobeView.yaw += (e.clientX - last[0]) * 0.01;
    lobeView.pitch = Math.max(-0.2, Math.min(1.5, lobeView.pitch + (e.clientY - last[1]) * 0.01));
    last = [e.clientX, e.clientY];
    redraw();
  });
}

/* ---- a slice for the light: any plane through the normal, polar or
 * Cartesian axes -------------------------------------------------------- */

function sliceCurves(gl, R) {
  const lum = (px) => Array.from({ length: px.length / 4 }, (_, k) => 0.2126 * px[4 * k] + 0.7152 * px[4 * k + 1] + 0.0722 * px[4 * k + 2]);
  const rec = sliceGrid(gl, R, 1), orig = D.ref ? sliceGrid(gl, R, 0) : null;
  return rec ? (orig ? [[lum(orig), '#fff', 2.5], [lum(rec), curveColour(S.terms), 1.5]] : [[lum(rec), curveColour(S.terms), 2]]) : null;
}

function drawSlice(gl, R) {
  const c = $('slice'), x = c.getContext('2d'), W = c.width, H = c.height, n = SLICE_N * SLICE_N;
  x.fillStyle = '#111';
  x.fillRect(0, 0, W, H);
  x.fillStyle = '#888';
  x.strokeStyle = '#444';
  const curves = sliceCurves(gl, R);
  if (!curves) return void x.fillText('no float render target: no slice', 10, 20);
  let peak = 0;
  for (const [v] of curves) for (const f of v) peak = Math.max(peak, f);
  const val = (f) => (S.log ? Math.max(0, Math.log10(Math.max(f, 1e-30) / peak) / 4 + 1) : Math.max(f, 0) / peak);
  const ox = W / 2, oy = H - 16, Rp = Math.min(W / 2 - 12, H - 30), x0 = 36, x1 = W - 10;
  const at = S.cartesian
    ? (to, v) => [x0 + ((to / Math.PI + 0.5) * (x1 - x0)), oy - v * Rp]
    : (to, v) => [ox + Math.sin(to) * v * Rp, oy - Math.cos(to) * v * Rp];
  x.beginPath();
  if (S.cartesian) {
    x.moveTo(x0, oy - Rp);
    x.lineTo(x0, oy);
    x.lineTo(x1, oy);
    for (const d of [-90, -45, 0, 45, 90]) x.fillText(d + '\u00b0', at((d * Math.PI) / 180, 0)[0] - 8, oy + 12);
  } else {
    for (const f of [0.5, 1]) x.arc(ox, oy, f * Rp, Math.PI, 2 * Math.PI);
    x.moveTo(ox, oy);
    x.lineTo(ox, oy - Rp);
  }
  x.stroke();
  x.fillText((S.cartesian ? 'Cartesian' : 'polar') + ', ' + (S.log ? 'log, 4 decades' : 'linear') + '; \u03b8o > 0 right', 6, 14);
  if (!(peak > 0)) return;
  for (const [v, colour, width] of curves) {
    x.strokeStyle = colour;
    x.lineWidth = width;
    x.beginPath();
    v.forEach((f, k) => (k ? x.lineTo : x.moveTo).apply(x, at(((k + 0.5) / n - 0.5) * Math.PI, val(f))));
    x.stroke();
  }
  x.lineWidth = 1;
}

/* ---- an HDR the user drops: Radiance RGBE (flat or RLE scanlines),
 * equirectangular (row 0 the zenith, u = phi / 2 pi), averaged into the
 * sky's cells: 4 x 4 points a cell, each the pixel it falls in, weighted
 * by sin theta ------------------------------------------------------------ */

function parseHDR(buf) {
  const b = new Uint8Array(buf);
  let p = 0, line = '';
  const next = () => { line = ''; while (p < b.length && b[p] !== 10) line += String.fromCharCode(b[p++]); p++; return line; };
  if (!/^#\?(RADIANCE|RGBE)/.test(next())) throw new Error('not a Radiance .hdr file');
  while (next() !== '') if (p >= b.length) throw new Error('.hdr: no end of header');
  const m = /^-Y (\d+) \+X (\d+)$/.exec(next());
  if (!m) throw new Error('.hdr: only -Y H +X W images');
  const H = +m[1], W = +m[2], rgbe = new Uint8Array(W * H * 4), row = new Uint8Array(W * 4);
  for (let y = 0; y < H; y++) {
    if (W >= 8 && W < 32768 && b[p] === 2 && b[p + 1] === 2 && ((b[p + 2] << 8) | b[p + 3]) === W) {
      p += 4;
      for (let c = 0; c < 4; c++)
        for (let x = 0; x < W; ) {
          let n = b[p++];
          if (!(n > 0)) throw new Error('.hdr: bad run');
          if (n > 128) {
            const v = b[p++];
            for (n -= 128; n-- > 0 && x < W; ) row[4 * x++ + c] = v;
          } else {
            while (n-- > 0 && x < W) row[4 * x++ + c] = b[p++];
          }
          if (p > b.length) throw new Error('.hdr: truncated');
        }
      rgbe.set(row, y * W * 4);
    } else {
      if (p + W * 4 > b.length) throw new Error('.hdr: truncated');
      rgbe.set(b.subarray(p, p + W * 4), y * W * 4);
      p += W * 4;
    }
  }
  const f = new Float32Array(W * H * 3);
  for (let i = 0; i < W * H; i++) {
    const e = rgbe[4 * i + 3], s = e ? Math.pow(2, e - 136) : 0;
    for (let c = 0; c < 3; c++) f[3 * i + c] = rgbe[4 * i + c] * s;
  }
  return { W, H, f };
}

/* the sky's cells (SKY_NP x SKY_NT RGB, row i = theta cell) from an image */
function skyCells(img) {
  const out = new Float32Array(SKY_NT * SKY_NP * 3);
  for (let i = 0; i < SKY_NT; i++)
    for (let j = 0; j < SKY_NP; j++) {
      let w = 0;
      const o = 3 * (i * SKY_NP + j);
      for (let a = 0; a < 4; a++)
        for (let k = 0; k < 4; k++) {
          const th = ((i + (a + 0.5) / 4) * Math.PI) / SKY_NT, ph = ((j + (k + 0.5) / 4) * 2 * Math.PI) / SKY_NP;
          const x = Math.min(img.W - 1, Math.floor((ph / (2 * Math.PI)) * img.W)), y = Math.min(img.H - 1, Math.floor((th / Math.PI) * img.H));
          for (let c = 0; c < 3; c++) out[o + c] += Math.sin(th) * img.f[3 * (y * img.W + x) + c];
          w += Math.sin(th);
        }
      for (let c = 0; c < 3; c++) out[o + c] /= w;
    }
  return out;
}

/* unit 3: the sky's cells, zeros until an HDR comes; u_sky_hdr says which */
function setSky(gl, R, cells) {
  gl.activeTexture(gl.TEXTURE3);
  gl.bindTexture(gl.TEXTURE_2D, gl.createTexture());
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGB32F, SKY_NP, SKY_NT, 0, gl.RGB, gl.FLOAT, cells || new Float32Array(SKY_NT * SKY_NP * 3));
  gl.uniform1i(R.U('u_sky'), 3);
  gl.uniform1i(R.U('u_sky_hdr'), cells ? 1 : 0);
}

/* test mode: ?hdr=BASE64URL, a .hdr file as if dropped */
function skyFromQuery(gl, R) {
  const q = Q.get('hdr');
  if (!q) return setSky(gl, R, null);
  const bin = atob(q.replace(/-/g, '+').replace(/_/g, '/')), u = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) u[i] = bin.charCodeAt(i);
  setSky(gl, R, skyCells(parseHDR(u.buffer)));
  S.shape = 2;
}

/* the page: an .hdr dropped anywhere lights the sphere */
function bindDrop(gl, R, redraw) {
  document.addEventListener('dragover', (e) => e.preventDefault());
  document.addEventListener('drop', (e) => {
    e.preventDefault();
    const file = e.dataTransfer.files[0];
    if (!file) return;
    file.arrayBuffer().then((buf) => {
      setSky(gl, R, skyCells(parseHDR(buf)));
      S.shape = 2;
      $('shape').value = 2;
      $('status').textContent = '';
      redraw();
    }).catch((err) => ($('status').textContent = 'error: ' + file.name + ': ' + err.message));
  });
}
