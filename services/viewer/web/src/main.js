// godhand viewer page: the scene (meshes fetched from the viewer, posed by SceneState), every God
// hand solid and its targets as a translucent ghost, contact points and force arrows, stale / held
// marks, live figures and a per-stage time chart; live over the Foxglove WebSocket feed or offline
// from a godhand-bench --poses file (timeline). window.godhand exposes what was drawn (for tests).
//
// Cost: a frame is drawn only when something changed (a state arrived, the camera moved, the
// window resized, a mesh loaded, the timeline played), at most ?fps= times a second (30), and
// never while the tab is hidden; the figures and the chart are redrawn twice a second. URL
// parameters: fps (frame-rate cap), scale (pixel ratio), aa (0/1: antialiasing), detail
// (full/light: the bodies' tessellation and the scene meshes; light where WebGL is software).
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { Feed } from './feed.js';

// Colours: God hands solid (right blue, left green, others violet); ghosts translucent orange /
// pink; contacts yellow points, force arrows red. The Chromium test checks for these hues.
const GOD_COLOURS = [0x2f7fe0, 0x28b45a, 0x9a5ae0];
const GHOST_COLOURS = [0xff8a1e, 0xff4fb0, 0xffd21e];
const STALE_COLOUR = 0xd23c3c;

const view = document.getElementById('view');
const params = new URLSearchParams(location.search);
// Software WebGL (SwiftShader, llvmpipe: headless Chromium, machines without a GPU) draws about
// twice as fast without multisampling; ?aa=0 / ?aa=1 overrides.
function softwareGl() {
  try {
    const gl = document.createElement('canvas').getContext('webgl2');
    const ext = gl && gl.getExtension('WEBGL_debug_renderer_info');
    const name = ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : '';
    const lose = gl && gl.getExtension('WEBGL_lose_context');
    if (lose) lose.loseContext();  // the probe's context is not kept
    return /swiftshader|llvmpipe|software/i.test(name);
  } catch { return false; }
}
const SOFTWARE_GL = softwareGl();
const aaParam = params.get('aa');
const renderer = new THREE.WebGLRenderer({ antialias: aaParam === null ? !SOFTWARE_GL : aaParam === '1', powerPreference: 'low-power' });
// Software WebGL pays for every pixel: draw at 0.6 of the CSS resolution there; a GPU at the
// screen's pixel ratio up to 1.5 (?scale= overrides either).
const scaleParam = Number(params.get('scale'));
renderer.setPixelRatio(scaleParam > 0 ? scaleParam : SOFTWARE_GL ? 0.6 : Math.min(1.5, window.devicePixelRatio || 1));
const fpsParam = Number(params.get('fps'));
const MAX_FPS = fpsParam > 0 ? Math.min(fpsParam, 240) : 30;
// ...and about half a microsecond on every triangle, however small on screen (headless Chromium's
// SwiftShader, 800x600: two hands' 32 God capsules took 8.8 ms a frame at 600 triangles each,
// 4.1 ms at 208; the default scene's 48k triangles 25 ms, 14k 11 ms). There the bodies are
// tessellated more coarsely and the scene's meshes are the viewer's light ones (a quarter of the
// triangles); ?detail=full / ?detail=light overrides.
const detailParam = params.get('detail');
const LIGHT = detailParam ? detailParam === 'light' : SOFTWARE_GL;
const CAPSULE_SEGMENTS = LIGHT ? [3, 8] : [6, 12], SPHERE_SEGMENTS = LIGHT ? [10, 8] : [16, 12];
renderer.setSize(view.clientWidth, view.clientHeight);
view.appendChild(renderer.domElement);
function timed(what, f) {
  const t = performance.now();
  f();
  godhand.cost[what] += performance.now() - t;
}

// ---------- drawing on demand ----------
// requestRender() asks for a frame: drawn at the next animation frame at most MAX_FPS times a
// second, so every change is drawn (the newest state of a burst, never an older one) while a
// burst of them costs one frame. Hidden tabs run no animation frames: nothing is drawn there
// until the tab shows again. Nothing changes, nothing is drawn.
let renderWanted = false, renderQueued = false, lastDrawAt = -Infinity;
const DRAW_GAP_MS = 1000 / MAX_FPS;
function requestRender() {
  renderWanted = true;
  if (!renderQueued) { renderQueued = true; requestAnimationFrame(drawFrame); }
}
function drawFrame(t) {
  renderQueued = false;
  if (!renderWanted) return;
  // Early by less than a quarter of a 60 Hz display's frame counts as on time (a 30 fps cap there
  // draws every second frame); a long wait sleeps in a timer, not in empty animation frames.
  const wait = DRAW_GAP_MS - (t - lastDrawAt);
  if (wait > 4) {
    renderQueued = true;
    if (wait > 24) setTimeout(() => requestAnimationFrame(drawFrame), wait - 17);
    else requestAnimationFrame(drawFrame);
    return;
  }
  renderWanted = false;
  lastDrawAt = t;
  if (offline && offline.playing) { offline.advance(t); requestRender(); }
  timed('draw', () => renderer.render(scene, camera));
  godhand.renders++;
  renderRate.tick();
  recordDrawn();
}

const scene = new THREE.Scene();
scene.background = new THREE.Color(0x202226);
const camera = new THREE.PerspectiveCamera(45, view.clientWidth / view.clientHeight, 0.005, 50);
camera.up.set(0, 0, 1);
camera.position.set(0.55, -0.65, 0.55);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0, 0, 0.1);
controls.update();
controls.addEventListener('change', () => requestRender());
scene.add(new THREE.HemisphereLight(0xffffff, 0x404048, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(0.5, -0.8, 1.5);
scene.add(sun);
const grid = new THREE.GridHelper(2, 40, 0x444a52, 0x33373d);
grid.rotation.x = Math.PI / 2;
scene.add(grid);
// The figures panel covers the left of the view: the picture's centre is shifted right by half of it.
function fitView() {
  const w = view.clientWidth, h = view.clientHeight;
  camera.aspect = w / h;
  const hud = document.getElementById('hud');
  const shift = hud && w > 700 ? Math.min(hud.offsetWidth / 2, w * 0.2) : 0;
  camera.setViewOffset(w, h, -shift, 0, w, h);
  camera.updateProjectionMatrix();
  renderer.setSize(w, h);
  requestRender();
}
window.addEventListener('resize', fitView);
fitView();

const nowNs = () => (performance.timeOrigin + performance.now()) * 1e6;
const setPose = (obj, p) => {
  if (!p || p[0] === null || p[3] === null) { obj.visible = false; return; }
  obj.visible = true;
  obj.position.set(p[0], p[1], p[2]);
  obj.quaternion.set(p[4], p[5], p[6], p[3]);  // wire (w, x, y, z) -> three (x, y, z, w)
};

// ---------- the scene ----------
const sceneRoot = new THREE.Group();
scene.add(sceneRoot);
let sceneObjects = new Map();   // index -> Object3D
let sceneGeneration = null;
const staticMat = new THREE.MeshStandardMaterial({ color: 0x9aa0a8, roughness: 0.85, metalness: 0.0 });
const dynamicMat = new THREE.MeshStandardMaterial({ color: 0xc8b48c, roughness: 0.7, metalness: 0.0 });

async function loadScene(desc) {
  const key = `${desc.file}|${desc.generation}`;
  if (key === sceneGeneration) return;
  sceneGeneration = key;
  for (const o of sceneObjects.values()) sceneRoot.remove(o);
  sceneObjects = new Map();
  godhand.scene = { name: desc.name, objects: desc.objects.length, meshes: 0, triangles: 0 };
  for (const o of desc.objects) {
    const holder = new THREE.Group();
    setPose(holder, o.pose);
    sceneRoot.add(holder);
    sceneObjects.set(o.index, holder);
    if (!desc.generation) {
      holder.add(new THREE.Mesh(new THREE.BoxGeometry(0.05, 0.05, 0.05), o.dynamic ? dynamicMat : staticMat));
      continue;
    }
    fetchRetrying(`mesh/${desc.generation}/${o.index}${LIGHT ? '.light' : ''}.bin`).then((r) => (r.ok ? r.arrayBuffer() : null)).then((buf) => {
      if (!buf || sceneObjects.get(o.index) !== holder) return;
      const dv = new DataView(buf);
      if (dv.getUint32(0, true) !== 0x314d4847) return;  // "GHM1"
      const nv = dv.getUint32(4, true), nt = dv.getUint32(8, true);
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(buf, 12, nv * 3), 3));
      g.setIndex(new THREE.BufferAttribute(new Uint32Array(buf, 12 + 12 * nv, nt * 3), 1));
      g.computeVertexNormals();
      holder.add(new THREE.Mesh(g, o.dynamic ? dynamicMat : staticMat));
      godhand.scene.meshes++;
      godhand.scene.triangles += nt;
      requestRender();
    });
  }
}

// The viewer answers 503 (Retry-After) while too many responses are on their way, from this
// address or all together (services/viewer/server.cc): try again, a few times, rather than
// leave a mesh out.
async function fetchRetrying(url, tries = 6) {
  for (let i = 1; ; i++) {
    const r = await fetch(url);
    if (r.status !== 503 || i >= tries) return r;
    await new Promise((resolve) => setTimeout(resolve, 250 * i));
  }
}

function applySceneState(s) {
  for (const o of s.objects) {
    const h = sceneObjects.get(o.index);
    if (h) setPose(h, o.pose);
  }
}

// ---------- hands ----------
const geometryCache = new Map();
function bodyGeometry(shape) {
  const key = shape.join(',');
  let g = geometryCache.get(key);
  if (g) return g;
  const [type, r, hl, hx, hy, hz] = shape;
  if (type === 0) {
    g = new THREE.CapsuleGeometry(Math.max(r, 1e-4), Math.max(2 * hl, 1e-6), ...CAPSULE_SEGMENTS);
    g.rotateX(Math.PI / 2);  // three's capsule runs along y; the body's along z
  } else if (type === 1) {
    g = new THREE.SphereGeometry(Math.max(r, 1e-4), ...SPHERE_SEGMENTS);
  } else {
    g = new THREE.BoxGeometry(2 * hx + 2 * r, 2 * hy + 2 * r, 2 * hz + 2 * r);
  }
  geometryCache.set(key, g);
  return g;
}

const sameShapes = (a, b) => !!b && a.length === b.length && a.every((s, i) => s.length === b[i].length && s.every((v, k) => v === b[i][k]));

class HandView {
  constructor(index, name) {
    this.index = index;
    this.name = name;
    const c = GOD_COLOURS[index % GOD_COLOURS.length];
    this.godMat = new THREE.MeshStandardMaterial({ color: c, roughness: 0.5, metalness: 0.05 });
    this.godColour = c;
    this.ghostMat = new THREE.MeshBasicMaterial({ color: GHOST_COLOURS[index % GHOST_COLOURS.length], transparent: true,
      opacity: 0.38, depthWrite: false });
    this.god = new THREE.Group();
    this.ghost = new THREE.Group();
    this.ghost.renderOrder = 2;
    this.ghost.visible = false;  // until the first target
    scene.add(this.god, this.ghost);
    this.godBodies = [];
    this.ghostBodies = [];
    this.shapes = null;
    this.state = null;
    this.target = null;
    this.drawnFrame = 0;
    this.pendingRecv = null;
    this.rate = new RateMeter();
  }

  ensureBodies(shapes) {
    if (sameShapes(shapes, this.shapes)) return;
    this.shapes = shapes;
    for (const m of this.godBodies) this.god.remove(m);
    for (const m of this.ghostBodies) this.ghost.remove(m);
    this.godBodies = shapes.map((s) => new THREE.Mesh(bodyGeometry(s), this.godMat));
    this.ghostBodies = shapes.map((s) => new THREE.Mesh(bodyGeometry(s), this.ghostMat));
    this.god.add(...this.godBodies);
    this.ghost.add(...this.ghostBodies);
  }

  setState(s) {
    this.ensureBodies(s.shapes);
    this.state = s;
    s.poses.forEach((p, b) => setPose(this.godBodies[b], p));
    this.god.visible = s.started;
    const marked = s.stale || s.held;
    this.godMat.color.setHex(s.stale ? STALE_COLOUR : this.godColour);
    this.godMat.emissive.setHex(marked ? 0x331010 : 0x000000);
    this.pendingRecv = s.recv_ns;
    this.pendingFrame = s.stamp.frame;
    if (s.penetration_m !== null && s.penetration_m !== undefined) this.penMax = Math.max(this.penMax || 0, s.penetration_m);
    this.rate.tick();
  }

  setTargets(targets, driven, tracked) {
    if (!this.ghostBodies.length) return;
    this.target = { targets, driven, tracked };
    this.ghost.visible = tracked !== false;
    targets.forEach((p, b) => {
      if (b < this.ghostBodies.length) {
        setPose(this.ghostBodies[b], driven && driven[b] === false ? null : p);
      }
    });
  }

  // Mean distance (m) from each God body to its target: the tracking lag.
  lag() {
    if (!this.state || !this.target) return null;
    let sum = 0, n = 0;
    this.state.poses.forEach((p, b) => {
      const t = this.target.targets[b];
      if (!t || !p || p[0] === null || t[0] === null) return;
      sum += Math.hypot(p[0] - t[0], p[1] - t[1], p[2] - t[2]);
      n++;
    });
    return n ? sum / n : null;
  }
}

class RateMeter {
  constructor() { this.times = []; }
  tick() { const t = performance.now(); this.times.push(t); while (this.times.length && t - this.times[0] > 2000) this.times.shift(); }
  hz() { const t = performance.now(); while (this.times.length && t - this.times[0] > 2000) this.times.shift(); return this.times.length / 2; }
}

const hands = new Map();  // index -> HandView
function hand(index, name) {
  let h = hands.get(index);
  if (!h) { h = new HandView(index, name); hands.set(index, h); }
  return h;
}

// ---------- contacts ----------
// Every contact point, arrow shaft and arrow head in one draw call each (instances, one line
// buffer), up to MAX_CONTACTS; a force arrow is 1.5 cm plus 3 cm per N, at most 8 cm.
const MAX_CONTACTS = 320;
const FORCE_SCALE = 0.03;  // m per N
const HEAD_LENGTH = 0.007, HEAD_WIDTH = 0.005;
const contactPoints = new THREE.InstancedMesh(new THREE.SphereGeometry(0.003, 8, 6), new THREE.MeshBasicMaterial({ color: 0xffe14d }), MAX_CONTACTS);
const arrowHeads = new THREE.InstancedMesh(new THREE.ConeGeometry(0.5, 1, 5, 1).translate(0, 0.5, 0),  // base at 0, tip at +y 1
  new THREE.MeshBasicMaterial({ color: 0xff2020, toneMapped: false }), MAX_CONTACTS);
const shaftGeometry = new THREE.BufferGeometry();
shaftGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(6 * MAX_CONTACTS), 3).setUsage(THREE.DynamicDrawUsage));
const shafts = new THREE.LineSegments(shaftGeometry, new THREE.LineBasicMaterial({ color: 0xff2020, toneMapped: false }));
for (const o of [contactPoints, arrowHeads, shafts]) {
  o.frustumCulled = false;  // their bounds change with every message
  scene.add(o);
}
contactPoints.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
arrowHeads.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
const dir = new THREE.Vector3(), at = new THREE.Vector3(), headAt = new THREE.Vector3(), turn = new THREE.Quaternion();
const unitScale = new THREE.Vector3(1, 1, 1), headScale = new THREE.Vector3(HEAD_WIDTH, HEAD_LENGTH, HEAD_WIDTH);
const yAxis = new THREE.Vector3(0, 1, 0), noTurn = new THREE.Quaternion(), tmpMatrix = new THREE.Matrix4();
function setContacts(list) {
  const shaft = shaftGeometry.attributes.position.array;
  let n = 0;
  for (const c of list) {
    if (n === MAX_CONTACTS) break;
    if (!c || c.p[0] === null || c.n[0] === null) continue;
    at.set(c.p[0], c.p[1], c.p[2]);
    dir.set(c.n[0], c.n[1], c.n[2]).normalize();
    const length = Math.min(0.08, 0.015 + FORCE_SCALE * Math.max(0, c.lambda || 0));
    headAt.copy(at).addScaledVector(dir, length - HEAD_LENGTH);
    contactPoints.setMatrixAt(n, tmpMatrix.compose(at, noTurn, unitScale));
    arrowHeads.setMatrixAt(n, tmpMatrix.compose(headAt, turn.setFromUnitVectors(yAxis, dir), headScale));
    at.toArray(shaft, 6 * n);
    headAt.toArray(shaft, 6 * n + 3);
    n++;
  }
  contactPoints.count = arrowHeads.count = n;
  contactPoints.instanceMatrix.needsUpdate = arrowHeads.instanceMatrix.needsUpdate = true;
  shaftGeometry.setDrawRange(0, 2 * n);
  shaftGeometry.attributes.position.needsUpdate = true;
  godhand.contacts = list.length;
}

// ---------- figures ----------
const STAGES = [['contacts', '#4fa3ff'], ['assembly', '#a0a0ff'], ['solve', '#ffb04f'], ['integrate', '#7fd67f'],
  ['ccd', '#ff6f6f'], ['merge', '#d0d0d0'], ['scene', '#c8b48c']];
document.getElementById('legend').innerHTML = STAGES.map(([n, c]) => `<span><i style="background:${c}"></i>${n}</span>`).join('');
const chart = document.getElementById('chart').getContext('2d');
const history = [];  // per HandState (hand 0's, plus the scene step): stage times in us
let sceneStepUs = 0;
const latencies = [];     // recv -> drawn (ms), newest last
const arrivals = [];      // recv -> arrived in the page (ms): the viewer's and the socket's share
const e2e = [];           // tracker sample -> drawn (ms)
const services = new Map();
let viewerStats = null;
const renderRate = new RateMeter();

// Median and 99th percentile from one sort; '–' for none.
function medianP99(a) {
  if (!a.length) return '–';
  const s = Float64Array.from(a).sort();
  return `${fmt(s[Math.floor(s.length / 2)])} ms (p99 ${fmt(s[Math.min(s.length - 1, Math.floor(0.99 * s.length))])})`;
}
const fmt = (v, d = 1) => (v === null || v === undefined || Number.isNaN(v) ? '–' : Number(v).toFixed(d));

function drawChart() {
  const w = chart.canvas.width, hgt = chart.canvas.height;
  chart.clearRect(0, 0, w, hgt);
  const n = history.length;
  if (!n) return;
  // Scaled to the 95th percentile of the frame totals (one slow frame would flatten every bar).
  const totals = history.map((h) => STAGES.reduce((s, [k]) => s + (h[k] || 0), 0)).sort((x, y) => x - y);
  const max = Math.max(200, totals[Math.floor(0.95 * (totals.length - 1))]);
  const bw = w / 100;
  history.forEach((h, i) => {
    let y = hgt;
    for (const [k, c] of STAGES) {
      const v = ((h[k] || 0) / max) * (hgt - 12);
      chart.fillStyle = c;
      chart.fillRect(i * bw, Math.max(12, y - v), Math.max(1, bw - 0.5), Math.max(0, Math.min(v, y - 12)));
      y -= v;
    }
  });
  chart.fillStyle = '#ccc';
  chart.font = '10px sans-serif';
  chart.fillText(`per-stage time per frame, µs (scale ${max.toFixed(0)})`, 4, 10);
}

function updateHud() {
  const rows = [];
  rows.push(['render', `${fmt(renderRate.hz(), 0)} fps`]);
  rows.push(['feed', feed ? `${fmt(feed.received, 0)} msgs` : 'offline file']);
  if (latencies.length) {
    rows.push(['viewer → page', medianP99(arrivals)]);
    rows.push(['viewer → drawn', medianP99(latencies)]);
    rows.push(['tracker → drawn', medianP99(e2e)]);
  }
  if (viewerStats) {
    // Older messages a slow browser never got, the newest of each hand sent instead (feed.h).
    rows.push(['dropped (slow browsers)', `${viewerStats.dropped}`]);
    const mine = feed && viewerStats.per_client ? viewerStats.per_client.find((c) => c.id === feed.sessionId) : null;
    if (mine) rows.push(['skipped for this page (it fell behind)', `${mine.superseded}`]);
  }
  setHtml('figures', rows.map(([k, v]) => `<tr><td>${k}</td><td class="v">${v}</td></tr>`).join(''));
  const hs = [...hands.values()].sort((a, b) => a.index - b.index).map((h) => {
    const s = h.state;
    let badge = '<span class="badge off">waiting</span>';
    if (s) badge = s.stale ? '<span class="badge stale">STALE</span>' : s.held ? '<span class="badge held">held</span>' : '<span class="badge fresh">live</span>';
    if (s && !s.tracked) badge += '<span class="badge off">untracked</span>';
    const pen = s && s.penetration_m !== null && s.penetration_m !== undefined ? `${fmt(s.penetration_m * 1000, 3)} mm` : '–';
    const lag = h.lag();
    return `<div id="hand-${h.index}" data-stale="${s ? s.stale : ''}" data-held="${s ? s.held : ''}">` +
      `<b style="color:#${h.godColour.toString(16).padStart(6, '0')}">${h.name}</b> ${badge} ` +
      `${fmt(h.rate.hz(), 0)} Hz · frame ${s ? s.stamp.frame : '–'} · contacts ${s && s.contacts !== null && s.contacts !== undefined ? s.contacts : '–'} · ` +
      `penetration ${pen} · lag ${lag === null ? '–' : fmt(lag * 1000, 1) + ' mm'}</div>`;
  });
  setHtml('hands', hs.join(''));
  const svc = [...services.values()].sort((a, b) => a.service.localeCompare(b.service)).map((s) => {
    const age = (nowNs() - s.recv_ns) / 1e9;
    const state = age > 2 ? 'gone' : s.state;
    return `<tr><td>${s.service}</td><td><span class="badge ${state === 'running' ? 'fresh' : 'stale'}">${state}</span></td>` +
      `<td class="v">${fmt(s.rate_hz, 1)} Hz</td><td class="v">${fmt(s.latency_median_us / 1000, 2)} ms</td></tr>`;
  });
  setHtml('services', svc.join(''));
  if (history.length !== chartDrawn.n || history[history.length - 1] !== chartDrawn.last) {
    chartDrawn.n = history.length;
    chartDrawn.last = history[history.length - 1];
    drawChart();
  }
}
// The DOM is touched only where its text changed (each change costs a style, layout and paint).
const htmlNow = new Map();
function setHtml(id, html) {
  if (htmlNow.get(id) === html) return;
  htmlNow.set(id, html);
  document.getElementById(id).innerHTML = html;
}
const chartDrawn = { n: -1, last: null };
// Twice a second, and not at all while the tab is hidden.
setInterval(() => { if (!document.hidden) timed('hud', updateHud); }, 500);

// ---------- test hooks ----------
const godhand = {
  mode: null,
  connected: false,
  scene: null,
  contacts: 0,
  received: { hand_state: 0, hand_target: 0, scene_state: 0, contact_forces: 0, service_status: 0, scene_description: 0 },
  renders: 0,
  maxFps: MAX_FPS,
  // Where the page's main thread spent its time (performance.now(), ms, cumulative): drawing the
  // frames, taking the feed's messages, the figures.
  cost: { draw: 0, messages: 0, hud: 0 },
  renderInfo: () => ({ ...renderer.info.render }),  // the last frame's draw calls and triangles
  latenciesMs: latencies,
  arrivalMs: arrivals,
  endToEndMs: e2e,
  // What was drawn in the last rendered frame, per hand: frame, stale/held, and each God body's
  // world pose read back from three.js ([px, py, pz, qw, qx, qy, qz]).
  drawn: {},
  hands: () => [...hands.keys()],
  offline: null,
  freeze: false,
};
window.godhand = godhand;

const tmpP = new THREE.Vector3(), tmpQ = new THREE.Quaternion(), tmpS = new THREE.Vector3();
function readPose(m) {
  m.matrixWorld.decompose(tmpP, tmpQ, tmpS);
  return [tmpP.x, tmpP.y, tmpP.z, tmpQ.w, tmpQ.x, tmpQ.y, tmpQ.z];
}
function recordDrawn() {
  const t = nowNs();
  for (const h of hands.values()) {
    if (!h.state) continue;
    const poses = h.godBodies.map(readPose);
    const ghost = h.ghostBodies.map(readPose);
    godhand.drawn[h.index] = { cluster: h.name, frame: h.pendingFrame, run: h.state.stamp.run, stale: h.state.stale, held: h.state.held,
      penetrationMax: h.penMax === undefined ? null : h.penMax,
      poses, ghost, ghostVisible: h.ghost.visible };
    if (h.pendingRecv) {
      latencies.push((t - h.pendingRecv) / 1e6);
      if (h.state.stamp.source_ns > 0) e2e.push((t - h.state.stamp.source_ns) / 1e6);
      if (latencies.length > 2000) latencies.shift();
      if (e2e.length > 2000) e2e.shift();
      h.pendingRecv = null;
    }
  }
}

// ---------- live ----------
let feed = null;
let framedCamera = false;
let firstStateAt = 0;
// Frames the camera once on every hand that has a state (waits up to 1 s for a second hand).
function frameCamera() {
  if (framedCamera) return;
  const withState = [...hands.values()].filter((h) => h.state && h.state.started && h.state.poses.length && h.state.poses[0][0] !== null);
  if (!withState.length) return;
  if (!firstStateAt) firstStateAt = performance.now();
  if (withState.length < 2 && performance.now() - firstStateAt < 1000) return;
  framedCamera = true;
  const box = new THREE.Box3();
  for (const h of withState) for (const p of h.state.poses) if (p[0] !== null) box.expandByPoint(new THREE.Vector3(p[0], p[1], p[2]));
  const c = box.getCenter(new THREE.Vector3());
  const r = Math.max(0.12, box.getSize(new THREE.Vector3()).length());
  controls.target.copy(c);
  camera.position.set(c.x + 0.9 * r, c.y - 1.6 * r, c.z + 1.1 * r);
  controls.update();
}

function onMessage(topic, m) {
  const kind = topic.replace('godhand/', '');
  if (godhand.received[kind] !== undefined) godhand.received[kind]++;
  if (godhand.freeze) return;  // tests: hold the picture still (messages counted, not drawn)
  timed('messages', () => applyMessage(kind, m));
}

function applyMessage(kind, m) {
  switch (kind) {
    case 'hand_state': {
      if (m.recv_ns) { arrivals.push((nowNs() - m.recv_ns) / 1e6); if (arrivals.length > 2000) arrivals.shift(); }
      const h = hand(m.hand, m.cluster);
      h.setState(m);
      frameCamera();
      if (m.hand === Math.min(...hands.keys())) {
        history.push({ ...m.times_us, scene: sceneStepUs });
        if (history.length > 100) history.shift();
      }
      requestRender();
      break;
    }
    case 'hand_target': {
      const h = hand(m.hand, m.cluster);
      if (!synthetic.owns(m.hand)) h.setTargets(m.targets, m.driven, m.tracked);
      requestRender();
      break;
    }
    case 'scene_description': loadScene(m); requestRender(); break;
    case 'scene_state': sceneStepUs = m.step_us || 0; applySceneState(m); requestRender(); break;
    case 'contact_forces': setContacts(m.contacts); requestRender(); break;
    case 'service_status': services.set(m.service, m); break;
    case 'viewer_stats': viewerStats = m; godhand.viewerStats = m; break;
    default: break;
  }
}

function startLive() {
  document.getElementById('mode').textContent = 'live';
  const conn = document.getElementById('conn');
  feed = new Feed(`ws://${location.host}/`, {
    onMessage,
    onOpen: () => { godhand.connected = true; conn.textContent = 'connected'; conn.className = 'badge fresh'; },
    onClose: () => { godhand.connected = false; conn.textContent = 'reconnecting'; conn.className = 'badge stale'; },
  });
  godhand.feed = feed;
}

// ---------- synthetic hand (no tracker): the page moves a hand's target ----------
// With godhand-viewer --synthetic CLUSTER the viewer publishes that cluster's HandTarget (the hand
// at rest above the bunny, moved by an offset); the page sets the offset: W/S (y), A/D (x), Q/E
// (down/up) or Shift-drag in the view plane. The ghost shows the target, the solid hand where the
// method lets it go.
const synthetic = {
  hand: null, offset: new THREE.Vector3(), keys: new Set(), lastSent: 0, sentOffset: null, sent: 0, lastStep: 0,
  owns() { return false; },
  step() {
    if (this.hand === null || !feed) return;
    const now = performance.now();
    const dt = this.lastStep ? Math.min(0.1, (now - this.lastStep) / 1000) : 0;
    this.lastStep = now;
    const speed = 0.06 * dt, k = this.keys;  // 6 cm/s, whatever the frame rate
    if (k.has('w')) this.offset.y += speed; if (k.has('s')) this.offset.y -= speed;
    if (k.has('d')) this.offset.x += speed; if (k.has('a')) this.offset.x -= speed;
    if (k.has('e')) this.offset.z += speed; if (k.has('q')) this.offset.z -= speed;
    this.offset.clampScalar(-0.95, 0.95);
    const t = performance.now();
    const changed = !this.sentOffset || !this.sentOffset.equals(this.offset);
    if (t - this.lastSent < (changed ? 30 : 500)) return;
    if (feed.publish('godhand/synthetic_target', { hand: this.hand, offset: this.offset.toArray() })) {
      this.lastSent = t;
      this.sentOffset = this.offset.clone();
      this.sent++;
    }
  },
};
godhand.synthetic = synthetic;
window.addEventListener('keydown', (e) => synthetic.keys.add(e.key.toLowerCase()));
window.addEventListener('keyup', (e) => synthetic.keys.delete(e.key.toLowerCase()));
window.addEventListener('blur', () => synthetic.keys.clear());
let dragFrom = null;
renderer.domElement.addEventListener('pointerdown', (e) => { if (e.shiftKey && synthetic.hand !== null) { dragFrom = [e.clientX, e.clientY]; controls.enabled = false; } });
window.addEventListener('pointerup', () => { dragFrom = null; controls.enabled = true; });
window.addEventListener('pointermove', (e) => {
  if (!dragFrom) return;
  // Screen drag -> motion in the camera's view plane.
  const dx = (e.clientX - dragFrom[0]) * 0.0008, dy = (e.clientY - dragFrom[1]) * 0.0008;
  dragFrom = [e.clientX, e.clientY];
  const right = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 0);
  const up = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 1);
  synthetic.offset.addScaledVector(right, dx).addScaledVector(up, -dy);
});

// ---------- offline ----------
let offline = null;
async function startOffline() {
  document.getElementById('mode').textContent = 'offline';
  const data = await (await fetchRetrying('offline.json')).json();
  loadScene(data.scene);
  const tl = document.getElementById('timeline');
  tl.style.display = 'block';
  const scrub = document.getElementById('scrub');
  const label = document.getElementById('frame-label');
  const play = document.getElementById('play');
  scrub.max = String(data.frames.length - 1);
  data.hands.forEach((hd, i) => hand(i, hd.name));
  offline = {
    data, index: 0, playing: true, last: performance.now(), fps: 50,
    show(i) {
      this.index = Math.max(0, Math.min(data.frames.length - 1, i));
      scrub.value = String(this.index);
      label.textContent = `frame ${data.frames[this.index]} (${this.index + 1}/${data.frames.length})`;
      data.hands.forEach((hd, hi) => {
        const h = hands.get(hi);
        const flat = hd.poses[this.index];
        const poses = hd.shapes.map((_, b) => (flat ? flat.slice(7 * b, 7 * b + 7) : [null]));
        h.setState({ hand: hi, cluster: hd.name, stamp: { frame: data.frames[this.index], source_ns: 0, run: 0 }, recv_ns: null,
          tracked: !!flat, started: !!flat, stale: false, held: false, contacts: null, penetration_m: null, shapes: hd.shapes, poses });
        h.pendingRecv = null;
        if (hd.targets) {
          const tf = hd.targets[this.index];
          h.setTargets(hd.shapes.map((_, b) => (tf ? tf.slice(7 * b, 7 * b + 7) : [null])), null, !!tf);
        } else {
          h.ghost.visible = false;
        }
      });
      frameCamera();
      requestRender();
      godhand.offline = { frame: data.frames[this.index], index: this.index, frames: data.frames.length, hands: data.hands.length,
        has_targets: data.has_targets };
    },
    // Plays at the file's rate whatever the drawing rate: skips the frames that fell between two
    // drawn ones (after a pause or a hidden tab, goes on from where it was).
    advance(t) {
      if (t - this.last > 1000) this.last = t - 1000 / this.fps;
      const n = Math.max(0, Math.floor((t - this.last) * this.fps / 1000));
      if (!n) return;
      this.last += n * 1000 / this.fps;
      this.show((this.index + n) % data.frames.length);
    },
  };
  scrub.addEventListener('input', () => { offline.playing = false; play.textContent = 'play'; offline.show(Number(scrub.value)); });
  play.addEventListener('click', () => {
    offline.playing = !offline.playing;
    play.textContent = offline.playing ? 'pause' : 'play';
    offline.last = performance.now();
    requestRender();
  });
  godhand.showFrame = (i) => { offline.playing = false; play.textContent = 'play'; offline.show(i); };
  offline.show(0);
}

fetchRetrying('mode.json').then((r) => r.json()).then((m) => {
  godhand.mode = m.mode;
  const help = document.getElementById('synthetic-help');
  if (m.mode === 'live' && m.synthetic !== null && m.synthetic !== undefined) {
    synthetic.hand = m.synthetic;
    setInterval(() => synthetic.step(), 30);  // the keys move the target whatever is drawn
    help.innerHTML = 'synthetic hand: <b>W/A/S/D</b> move, <b>Q/E</b> down/up, or <b>Shift</b>-drag';
  } else {
    help.style.display = 'none';
  }
  if (m.mode === 'offline') startOffline(); else startLive();
});
requestRender();
