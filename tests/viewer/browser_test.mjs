// The browser viewer, end to end: Debian's chromium (headless, driven by playwright-core) against
// real godhand-viewer and godhand-launch processes on their own DDS domain. No mocks: the page
// is the bundled one, the feed the real Foxglove WebSocket server, the hands come from the real
// services. Every wait has a deadline; every process started here is stopped here.
//
// usage: node browser_test.mjs CASE BIN_DIR DEPLOY_DIR WEB_DIR DOMAIN
// cases: live | poses | offline | abuse | synthetic | screenshot | measure | cost
//   live     two live hands: connected, frames at the live rate, both hands drawn, a screenshot
//            with the God and ghost colours, stale marks while the scene service is killed, recovery;
//            drawn on demand (at most the frame-rate cap, nothing once nothing arrives, a drag draws)
//   poses    lock-step run: every God-body pose the page drew equals godhand-bench's --poses row
//            of that frame (the in-process run, bit-identical to the lock-step distributed one)
//   offline  godhand-viewer --poses on a bench CSV (with target columns added): timeline frames,
//            drawn God and ghost poses equal the file; bad command lines exit 2 with one line
//   abuse    malformed and oversized WebSocket messages, a client that never reads, 20 clients
//            connecting and leaving, bad HTTP: the viewer keeps serving the page at the live
//            rate and the services' run passes its --check
//   measure  (figures, not a pass/fail test) services' latency with 0 and 5 browsers, the
//            viewer's added latency and CPU, each page's CPU and frame rate, the whole
//            browser's CPU (BROWSER_NICE=19: the browsers at niceness 19; BROWSER_SCHED=idle:
//            under SCHED_IDLE; RUNS, PAGES, WEB_ROOT, PAGE_QUERY)
//   cost     (figures) what one page (PAGES) costs live and with nothing arriving
import { spawn, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';

const [CASE, BIN, DEPLOY, WEB, DOMAIN] = process.argv.slice(2);
const CHROMIUM = '/usr/bin/chromium';
const TMP = fs.mkdtempSync(path.join(os.tmpdir(), 'godhand-viewer-test-'));
const REC2 = path.join(DEPLOY, 'recordings', 'confidence2-49fps.json');
const REC1 = path.join(DEPLOY, 'recordings', 'pinch.json');
const failures = [];
const children = [];

function check(ok, what) {
  console.log((ok ? 'ok:     ' : 'FAILED: ') + what);
  if (!ok) failures.push(what);
}
function skip(why) {
  console.log('SKIP: ' + why);
  process.exit(77);
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

if (!fs.existsSync(CHROMIUM)) skip(`${CHROMIUM} not installed (Debian package chromium; deploy/install-deps.sh)`);
const pwPath = path.join(WEB, 'node_modules', 'playwright-core', 'index.mjs');
if (!fs.existsSync(pwPath)) skip(`${pwPath} missing (run npm ci in services/viewer/web; deploy/run.sh does)`);
const { chromium } = await import(pwPath);

// ---------- processes ----------
function start(cmd, args, name) {
  console.log('$ ' + [cmd, ...args].join(' '));
  const p = spawn(cmd, args, { stdio: ['ignore', 'pipe', 'pipe'] });
  p.out = '';
  p.err = '';
  p.stdout.on('data', (d) => { p.out += d; });
  p.stderr.on('data', (d) => { p.err += d; });
  p.exited = new Promise((resolve) => p.on('exit', (code, sig) => resolve({ code, sig })));
  p.name = name;
  children.push(p);
  return p;
}

async function stop(p, graceMs = 5000) {
  if (p.exitCode !== null || p.signalCode !== null) return p.exited;
  p.kill('SIGTERM');
  const t = setTimeout(() => p.kill('SIGKILL'), graceMs);
  const r = await p.exited;
  clearTimeout(t);
  return r;
}

async function startViewer(extra) {
  const v = start(path.join(BIN, 'godhand-viewer'), ['--port', '0', '--quiet', ...extra], 'viewer');
  const deadline = Date.now() + 30000;
  while (Date.now() < deadline) {
    const m = v.out.match(/^viewer: (http:\/\/127\.0\.0\.1:(\d+)\/)$/m);
    if (m) return { proc: v, url: m[1], port: Number(m[2]) };
    if (v.exitCode !== null) break;
    await sleep(50);
  }
  console.log(v.err);
  throw new Error('godhand-viewer did not print its URL line within 30 s');
}

function launch(extra) {
  const report = path.join(TMP, `launch-${Date.now()}.json`);
  const p = start(path.join(BIN, 'godhand-launch'),
    ['--domain', DOMAIN, '--quiet', '--json', report, '--log-dir', path.join(TMP, 'logs'), ...extra], 'launch');
  p.report = report;
  p.done = (async () => {
    const t = setTimeout(() => p.kill('SIGKILL'), 150000);
    const r = await p.exited;
    clearTimeout(t);
    if (r.code !== 0) console.log(p.out + '\n' + p.err);
    return { ...r, json: fs.existsSync(report) ? JSON.parse(fs.readFileSync(report, 'utf8')) : {} };
  })();
  return p;
}

function bench(recording, csv) {
  const r = spawnSync(path.join(BIN, 'godhand-bench'), ['--recording', recording, '--quiet', '--poses', csv], { timeout: 120000, encoding: 'utf8' });
  check(r.status === 0, `godhand-bench --poses ran (${r.status})`);
  return readCsv(csv);
}

function readCsv(file) {
  const lines = fs.readFileSync(file, 'utf8').trim().split('\n');
  const header = lines[0].split(',');
  const col = Object.fromEntries(header.map((h, i) => [h, i]));
  const rows = lines.slice(1).map((l) => l.split(','));
  return { header, col, rows, lines };
}

// ---------- the browser ----------
const FLAGS = ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
  '--disable-component-update', '--disable-sync'];
let browser = null;
async function openBrowser() {
  // playwright gives every launch a fresh, temporary --user-data-dir of its own. BROWSER_NICE=N
  // (measure): the browser and everything it starts run at that niceness, as browsers a lab
  // runs on the services' own machine should (the services keep their share of the cores).
  // BROWSER_SCHED=idle: under the SCHED_IDLE policy (chrt --idle), which any other task preempts.
  let exe = CHROMIUM;
  if (process.env.BROWSER_NICE || process.env.BROWSER_SCHED) {
    const nice = Number(process.env.BROWSER_NICE || 0);
    if (!(Number.isInteger(nice) && nice >= 0 && nice <= 19)) { console.log('BROWSER_NICE must be an integer in 0..19'); process.exit(2); }
    if (![undefined, 'idle'].includes(process.env.BROWSER_SCHED)) { console.log('BROWSER_SCHED must be idle'); process.exit(2); }
    const idle = process.env.BROWSER_SCHED === 'idle' ? 'chrt --idle 0 ' : '';
    exe = path.join(TMP, 'chromium-nice');
    fs.writeFileSync(exe, `#!/bin/sh\nexec ${idle}nice -n ${nice} ${CHROMIUM} "$@"\n`, { mode: 0o755 });
  }
  browser = await chromium.launch({ executablePath: exe, args: FLAGS, headless: true, timeout: 60000 });
  return browser;
}
async function openPage(url, size = { width: 1000, height: 700 }) {
  const page = await browser.newPage({ viewport: size });
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error') page.errors.push(m.text()); });
  await page.goto(url, { timeout: 30000 });
  return page;
}

// Counts the pixels of a PNG screenshot (decoded by the browser) near each named hue.
// The page's own panels (HUD, help, timeline) are left out: their badges use the same hues.
async function huePixels(page, png, hues) {
  const skip = await page.evaluate(() => ['hud', 'help', 'timeline'].map((id) => document.getElementById(id))
    .filter((e) => e && e.offsetParent !== null).map((e) => { const r = e.getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]; }));
  return page.evaluate(async ({ b64, hues, skip }) => {
    const blob = await (await fetch('data:image/png;base64,' + b64)).blob();
    const bmp = await createImageBitmap(blob);
    const c = new OffscreenCanvas(bmp.width, bmp.height);
    const g = c.getContext('2d');
    g.drawImage(bmp, 0, 0);
    const d = g.getImageData(0, 0, bmp.width, bmp.height).data;
    const out = Object.fromEntries(Object.keys(hues).map((k) => [k, 0]));
    const sx = bmp.width / window.innerWidth, sy = bmp.height / window.innerHeight;
    for (let i = 0; i < d.length; i += 4) {
      const x = (i / 4) % bmp.width, y = Math.floor(i / 4 / bmp.width);
      if (skip.some(([l, t, r, b]) => x >= l * sx && x <= r * sx && y >= t * sy && y <= b * sy)) continue;
      const r = d[i] / 255, gg = d[i + 1] / 255, b = d[i + 2] / 255;
      const max = Math.max(r, gg, b), min = Math.min(r, gg, b), s = max === 0 ? 0 : (max - min) / max;
      if (s < 0.45 || max < 0.25) continue;
      let h = 0;
      if (max === r) h = 60 * (((gg - b) / (max - min)) % 6);
      else if (max === gg) h = 60 * ((b - r) / (max - min) + 2);
      else h = 60 * ((r - gg) / (max - min) + 4);
      if (h < 0) h += 360;
      for (const [k, [lo, hi]] of Object.entries(hues)) if (h >= lo && h <= hi) out[k]++;
    }
    return out;
  }, { b64: png.toString('base64'), hues, skip });
}
// Hue bands of the page's colours (main.js): God right blue 0x2f7fe0 (~214), God left green
// 0x28b45a (~139), ghost right orange 0xff8a1e (~28), ghost left pink 0xff4fb0 (~327).
const HUES = { god_right: [200, 228], god_left: [125, 155], ghost_right: [18, 40], ghost_left: [312, 340] };

// ---------- pose comparison ----------
function quatClose(a, b) {
  const dot = Math.abs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]);
  return 1 - Math.min(1, dot);
}
function csvPoses(csv, frame, hand, prefix = '') {
  const c = csv.col;
  const out = [];
  for (const r of csv.rows) {
    if (Number(r[c.frame]) !== frame || r[c.hand] !== hand) continue;
    out.push(['px', 'py', 'pz', 'qw', 'qx', 'qy', 'qz'].map((k) => Number(r[c[prefix + k]])));
  }
  return out;
}
function poseError(drawn, expected) {
  if (drawn.length !== expected.length) return { pos: Infinity, rot: Infinity };
  let pos = 0, rot = 0;
  drawn.forEach((d, i) => {
    const e = expected[i];
    pos = Math.max(pos, Math.hypot(d[0] - e[0], d[1] - e[1], d[2] - e[2]));
    rot = Math.max(rot, quatClose(d.slice(3), e.slice(3)));
  });
  return { pos, rot };
}

// The largest distance between a drawn God body and its drawn ghost body (metres).
function separation(d) {
  let m = 0;
  d.poses.forEach((p, b) => { const g = d.ghost[b]; if (p && g) m = Math.max(m, Math.hypot(p[0] - g[0], p[1] - g[1], p[2] - g[2])); });
  return m;
}
function median(a) { const s = [...a].sort((x, y) => x - y); return s.length ? s[Math.floor(s.length / 2)] : NaN; }
function pct(a, p) { const s = [...a].sort((x, y) => x - y); return s.length ? s[Math.min(s.length - 1, Math.floor(p * s.length))] : NaN; }
async function stats(url) { return (await fetch(url + 'stats.json')).json(); }

function cpuSeconds(pid) {
  try {
    const f = fs.readFileSync(`/proc/${pid}/stat`, 'utf8');
    const parts = f.slice(f.lastIndexOf(')') + 2).split(' ');
    return (Number(parts[11]) + Number(parts[12])) / 100;  // utime + stime, clock ticks (100 Hz)
  } catch { return NaN; }
}

// ---------- cases ----------
async function caseLive() {
  const v = await startViewer(['--domain', DOMAIN]);
  await openBrowser();
  const page = await openPage(v.url);
  await page.waitForFunction(() => window.godhand && window.godhand.connected, null, { timeout: 20000 });
  check(true, 'the page connected to the viewer\'s WebSocket feed');
  const l = launch(['--recording', REC2, '--speed', '0.5', '--kill', 'scene@3', '--restart', '--restart-delay', '0.5']);
  // Sample what the page drew, every 100 ms, until the launch ends.
  const samples = [];
  let shot = null, shotPx = null, shotHands = null, freshRun = 0, shotEnd = 0, shots = 0, shotDone = false;
  let ended = false;
  l.done.then(() => { ended = true; });
  const t0 = Date.now();
  while (!ended && Date.now() - t0 < 120000) {
    const s = await page.evaluate(() => ({ t: Date.now(), drawn: JSON.parse(JSON.stringify(window.godhand.drawn)),
      received: { ...window.godhand.received }, renders: window.godhand.renders,
      badges: [...document.querySelectorAll('#hands > div')].map((d) => ({ id: d.id, stale: d.dataset.stale, text: d.textContent })) }));
    samples.push(s);
    const fresh = (drawn) => Object.values(drawn).filter((d) => !d.stale && d.ghostVisible).length;
    // A ghost that sits where its God hand is hides inside it (the God hand follows its targets in
    // free space): the picture is taken when every hand's ghost is at least 5 mm from its God hand.
    const apart = (drawn) => Object.values(drawn).filter((d) => !d.stale && d.ghostVisible && separation(d) > 0.005).length;
    // Both hands not stale for the last 4 samples (~0.4 s): a screenshot may show a frame drawn a
    // little before it was asked for.
    freshRun = fresh(s.drawn) === 2 ? freshRun + 1 : 0;
    if (!shotDone && shots < 4 && freshRun >= 2 && s.received.hand_target > 20 && apart(s.drawn) === 2) {
      // Hold the picture (the page stops applying messages), let it draw, and keep the
      // screenshot only when what it shows is both hands fresh with their ghosts apart; up to
      // four pictures, the one with the most ghost pixels of its fainter hand kept.
      await page.evaluate(() => { window.godhand.freeze = true; });
      await sleep(400);
      if (apart(await page.evaluate(() => window.godhand.drawn)) === 2) {
        const png = await page.screenshot();
        const px = await huePixels(page, png, HUES);
        shots++;
        if (!shot || Math.min(px.ghost_right, px.ghost_left) > Math.min(shotPx.ghost_right, shotPx.ghost_left)) {
          shot = png; shotPx = px; shotHands = 2;
          fs.writeFileSync(path.join(TMP, 'live.png'), png);
        }
        shotDone = px.ghost_right > 100 && px.ghost_left > 100;
      }
      await page.evaluate(() => { window.godhand.freeze = false; });
      shotEnd = Date.now();
    }
    await sleep(100);
  }
  const r = await l.done;
  check(r.code === 0, `godhand-launch with the scene kill drill exited 0 (${r.code})`);
  const j = r.json;
  const fd = j.fault_drill || {};
  check(fd.killed_s > 0 && fd.restarted_s > fd.killed_s, `the scene service was killed and restarted (${JSON.stringify(fd)})`);
  const last = samples[samples.length - 1] || { received: {}, drawn: {} };
  const fin = await page.evaluate(() => ({ received: window.godhand.received, lat: window.godhand.latenciesMs, e2e: window.godhand.endToEndMs,
    arr: window.godhand.arrivalMs,
    scene: window.godhand.scene, errors: [] }));
  // Frames at the live rate: the page received (nearly) every HandState the launcher's monitor saw.
  const states = j.hand_states !== undefined ? j.hand_states : (j.frames || 0) * (j.hands || 2);
  check(fin.received.hand_state >= 0.9 * states && states > 100,
    `the page received ${fin.received.hand_state} HandStates (the services published ~${states})`);
  // A 2 s window after the screenshot (taking one stalls the page's main thread for a while).
  const a = samples.find((x) => x.received.hand_state >= 20 && x.t > shotEnd + 500);
  const b = a && samples.find((x) => x.t >= a.t + 2000);
  if (a && b) {
    const rate = (b.received.hand_state - a.received.hand_state) / ((b.t - a.t) / 1000) / 2;
    // The services' own rate on this (shared, loaded) machine: the launcher's frames/s.
    const fps = j.frames_per_s || 0;
    check(fps > 5 && rate > 0.8 * fps, `live rate at the page: ${rate.toFixed(1)} HandStates/s per hand over 2 s; the services ran at ${fps.toFixed(1)} frames/s (recording 48.5 Hz at --speed 0.5 = 24.3)`);
  } else {
    check(false, 'live rate at the page measured');
  }
  check(new Set(samples.flatMap((s) => Object.values(s.drawn).map((d) => d.cluster))).size === 2, 'both hands were drawn (right and left)');
  check(fin.scene && fin.scene.meshes === fin.scene.objects && fin.scene.objects > 0,
    `the scene's meshes were fetched and drawn (${JSON.stringify(fin.scene)})`);
  // Stale while the scene was gone, fresh again after.
  let sawStale = false, recovered = false;
  for (const s of samples) {
    const d = Object.values(s.drawn);
    if (d.length && d.some((x) => x.stale)) sawStale = true;
    else if (sawStale && d.length === 2 && d.every((x) => !x.stale)) recovered = true;
  }
  const staleBadge = samples.some((s) => s.badges.some((b) => b.text.includes('STALE')));
  check(sawStale && staleBadge, 'hands drawn stale (and the STALE badge shown) while the scene service was killed');
  check(recovered, 'both hands drawn fresh again after the scene service restarted');
  // The screenshot: God and ghost colours of both hands.
  check(!!shot && shotHands === 2, `screenshot taken while both hands were drawn fresh with their ghosts apart (${shots} taken)`);
  if (shot) {
    const px = shotPx;
    check(px.god_right > 300 && px.god_left > 300, `God colours in the screenshot (right ${px.god_right} px, left ${px.god_left} px)`);
    check(px.ghost_right > 100 && px.ghost_left > 100, `ghost colours in the screenshot (right ${px.ghost_right} px, left ${px.ghost_left} px)`);
  }
  const lat = fin.lat.slice(5);
  check(lat.length > 50, `viewer -> drawn latency over ${lat.length} states: median ${median(lat).toFixed(1)} ms, p99 ${pct(lat, 0.99).toFixed(1)} ms`);
  console.log(`figure: HandState taken by the viewer -> in the page (before drawing) median ${median(fin.arr).toFixed(2)} ms, p99 ${pct(fin.arr, 0.99).toFixed(2)} ms`);
  console.log(`figure: tracker sample -> drawn median ${median(fin.e2e).toFixed(1)} ms, p99 ${pct(fin.e2e, 0.99).toFixed(1)} ms`);
  // Drawing on demand: never more than the page's frame-rate cap in any second of the run;
  // nothing drawn once nothing arrives; a drag of the camera draws.
  const cap = await page.evaluate(() => window.godhand.maxFps);
  let fastest = 0;
  for (const x of samples) {
    const y = samples.find((z) => z.t >= x.t + 1000);
    if (y) fastest = Math.max(fastest, (y.renders - x.renders) / ((y.t - x.t) / 1000));
  }
  check(cap === 30 && fastest > 5 && fastest <= 1.1 * cap, `frames drawn per second at most ${fastest.toFixed(1)} (cap ${cap})`);
  await sleep(1000);
  const still0 = await page.evaluate(() => window.godhand.renders);
  await sleep(2000);
  const still1 = await page.evaluate(() => window.godhand.renders);
  check(still1 === still0, `with nothing arriving, nothing drawn (${still1 - still0} frames in 2 s)`);
  await page.mouse.move(600, 400);
  await page.mouse.down();
  await page.mouse.move(660, 430, { steps: 4 });
  await page.mouse.up();
  const dragged = await page.waitForFunction((n) => window.godhand.renders > n, still1, { timeout: 5000 }).then(() => true, () => false);
  check(dragged, 'a camera drag draws');
  check(page.errors.length === 0, `no page errors (${page.errors.slice(0, 3).join(' | ')})`);
  await browser.close();
  const vr = await stop(v.proc);
  check(vr.code === 0, `godhand-viewer stopped cleanly on SIGTERM (${vr.code}${vr.sig ? ' ' + vr.sig : ''})`);
  // With the viewer still alive on the domain when the launch ends, the launch's own count may
  // include a segment the viewer still holds open; what matters is what is left once all is stopped.
  console.log(`figure: launch's shm_segments_left at its end (viewer still running): ${j.shm_segments_left}`);
}

async function casePoses() {
  const csvFile = path.join(TMP, 'bench.csv');
  const csv = bench(REC2, csvFile);
  const v = await startViewer(['--domain', DOMAIN]);
  await openBrowser();
  const page = await openPage(v.url);
  await page.waitForFunction(() => window.godhand && window.godhand.connected, null, { timeout: 20000 });
  // The page records every frame it drew (hand, frame, poses read back from three.js).
  await page.evaluate(() => {
    window.drawnLog = [];
    const seen = new Set();
    const tick = () => {
      for (const d of Object.values(window.godhand.drawn)) {
        const k = d.cluster + ':' + d.frame;
        if (!seen.has(k)) { seen.add(k); window.drawnLog.push(JSON.parse(JSON.stringify(d))); }
      }
      requestAnimationFrame(tick);
    };
    tick();
  });
  const l = launch(['--recording', REC2, '--lockstep']);
  const r = await l.done;
  check(r.code === 0, `godhand-launch --lockstep exited 0 (${r.code})`);
  await sleep(500);
  const log = await page.evaluate(() => window.drawnLog);
  let worstPos = 0, worstRot = 0, compared = 0, bodies = 0;
  const clusters = new Set();
  for (const d of log) {
    if (!d.frame) continue;
    // The CSV numbers frames from 0, the wire from 1 (Stamp.frame: tracker frame, 1-based).
    const e = csvPoses(csv, d.frame - 1, d.cluster);
    if (!e.length) continue;
    const err = poseError(d.poses, e);
    worstPos = Math.max(worstPos, err.pos);
    worstRot = Math.max(worstRot, err.rot);
    compared++;
    bodies += e.length;
    clusters.add(d.cluster);
  }
  check(compared >= 4 && clusters.size === 2, `compared ${compared} drawn frames (${bodies} God bodies) of both hands with godhand-bench's rows`);
  check(worstPos < 1e-9 && worstRot < 1e-12, `drawn God-body poses equal the in-process run's: max position error ${worstPos.toExponential(2)} m, max 1-|q.q'| ${worstRot.toExponential(2)}`);
  check(r.json.result_hash !== undefined, `lock-step result hash ${r.json.result_hash}`);
  check(page.errors.length === 0, `no page errors (${page.errors.slice(0, 3).join(' | ')})`);
  await browser.close();
  const vr = await stop(v.proc);
  check(vr.code === 0, `godhand-viewer stopped cleanly (${vr.code})`);
}

async function caseOffline() {
  // Bad command lines: one line, exit 2.
  const bad = path.join(TMP, 'bad.csv');
  fs.writeFileSync(bad, 'frame,hand,body\n1,right,palm\n');
  const cases = [
    [['--poses', path.join(TMP, 'missing.csv')], 'missing.csv'],
    [['--poses', bad], 'bad.csv:1: missing column'],
    [['--port', '70000'], '--port'],
    [['--domain', '999'], '--domain'],
    [['--bind', 'not-an-address'], '--bind'],
    [['--mesh', 'x.obj'], '--mesh'],
    [['--web-root', path.join(TMP, 'nopage')], 'index.html'],
    [['--bogus'], '--bogus'],
  ];
  for (const [args, expect] of cases) {
    const r = spawnSync(path.join(BIN, 'godhand-viewer'), [...args, '--domain', args.includes('--domain') ? '999' : DOMAIN], { timeout: 30000, encoding: 'utf8' });
    const lines = r.stderr.split('\n').filter((x) => x.trim() && !x.startsWith('try '));
    check(r.status === 2 && lines.length === 1 && lines[0].includes(expect), `godhand-viewer ${args.join(' ')}: exit ${r.status}, one line naming '${expect}': ${lines}`);
  }
  const h = spawnSync(path.join(BIN, 'godhand-viewer'), ['--help'], { encoding: 'utf8' });
  check(h.status === 0 && h.stdout.includes('--poses') && h.stdout.includes('--port'), 'godhand-viewer --help');

  // A bench file with its target columns: godhand-bench writes them (tpx..tqz); an older bench
  // without them gets them added here (the God pose moved 1 cm in x; the last body of each
  // frame without a target).
  const csvFile = path.join(TMP, 'bench.csv');
  const csv = bench(REC2, csvFile);
  const c = csv.col;
  let withTargets = csvFile;
  let tcsv = csv;
  if (c.tpx === undefined) {
    withTargets = path.join(TMP, 'bench-targets.csv');
    const out = [csv.header.join(',') + ',tpx,tpy,tpz,tqw,tqx,tqy,tqz'];
    csv.rows.forEach((r, i) => {
      const last = i + 1 === csv.rows.length || csv.rows[i + 1][c.frame] !== r[c.frame] || csv.rows[i + 1][c.hand] !== r[c.hand];
      const t = last ? ',,,,,,' : [Number(r[c.px]) + 0.01, r[c.py], r[c.pz], r[c.qw], r[c.qx], r[c.qy], r[c.qz]].join(',');
      out.push(r.join(',') + ',' + t);
    });
    fs.writeFileSync(withTargets, out.join('\n') + '\n');
    tcsv = readCsv(withTargets);
  } else {
    console.log('(the bench file has target columns of its own)');
  }
  // Expected ghost poses: the target columns, null where a row has none.
  const ghostExpected = (frame, hand) => tcsv.rows.filter((r) => Number(r[tcsv.col.frame]) === frame && r[tcsv.col.hand] === hand)
    .map((r) => (r[tcsv.col.tpx] === '' ? null : ['tpx', 'tpy', 'tpz', 'tqw', 'tqx', 'tqy', 'tqz'].map((k) => Number(r[tcsv.col[k]]))));
  const v = await startViewer(['--poses', withTargets, '--scene', path.join(DEPLOY, 'scenes', 'default.pbtxt')]);
  await openBrowser();
  const page = await openPage(v.url);
  await page.waitForFunction(() => window.godhand && window.godhand.offline, null, { timeout: 30000 });
  const frames = [...new Set(csv.rows.map((r) => Number(r[c.frame])))];
  const info = await page.evaluate(() => window.godhand.offline);
  check(info.frames === frames.length && info.hands === 2 && info.has_targets, `timeline over ${info.frames} frames of ${info.hands} hands with targets (file: ${frames.length})`);
  let worst = 0, worstGhost = 0, n = 0, ghostsCompared = 0;
  for (const idx of [0, Math.floor(frames.length / 2), frames.length - 1]) {
    await page.evaluate((i) => window.godhand.showFrame(i), idx);
    await page.waitForFunction((f) => Object.values(window.godhand.drawn).length === 2 && Object.values(window.godhand.drawn).every((d) => d.frame === f), frames[idx], { timeout: 10000 });
    const drawn = await page.evaluate(() => window.godhand.drawn);
    for (const d of Object.values(drawn)) {
      const e = csvPoses(csv, frames[idx], d.cluster);
      worst = Math.max(worst, poseError(d.poses, e).pos);
      const et = ghostExpected(frames[idx], d.cluster);
      const keep = et.map((t, b) => t !== null && b < d.ghost.length);
      worstGhost = Math.max(worstGhost, poseError(d.ghost.filter((_, b) => keep[b]), et.filter((_, b) => keep[b])).pos);
      ghostsCompared += keep.filter(Boolean).length;
      n++;
    }
  }
  check(n === 6 && worst < 1e-9, `drawn God poses equal the file at 3 timeline positions (max error ${worst.toExponential(2)} m)`);
  check(ghostsCompared > 20 && worstGhost < 1e-9, `${ghostsCompared} drawn ghost bodies sit at the file's target columns (max error ${worstGhost.toExponential(2)} m)`);
  // The screenshot at the frame where the targets are farthest from the God hand (a free hand's
  // ghost hides inside it).
  let far = 0, farIdx = 0;
  frames.forEach((f, i) => {
    for (const hd of ['right', 'left']) {
      const g = csvPoses(csv, f, hd), t = ghostExpected(f, hd);
      g.forEach((p, b) => { if (t[b]) { const dd = Math.hypot(p[0] - t[b][0], p[1] - t[b][1], p[2] - t[b][2]); if (dd > far) { far = dd; farIdx = i; } } });
    }
  });
  await page.evaluate((i) => window.godhand.showFrame(i), farIdx);
  await sleep(300);
  const shot = await page.screenshot({ path: path.join(TMP, 'offline.png') });
  const px = await huePixels(page, shot, HUES);
  check(px.god_right > 200 && px.ghost_right > 50, `offline screenshot shows God and ghost colours (${JSON.stringify(px)})`);
  const sc = await page.evaluate(() => window.godhand.scene);
  check(sc && sc.meshes === sc.objects && sc.triangles > 1000, `offline scene meshes drawn (${JSON.stringify(sc)})`);
  check(page.errors.length === 0, `no page errors (${page.errors.slice(0, 3).join(' | ')})`);
  const vr = await stop(v.proc);
  check(vr.code === 0, `godhand-viewer (offline) stopped cleanly (${vr.code})`);

  // The other models: two 6-body hands (the bench's --hand-model / --left-hand-model), and one
  // hand of a single body (a hand-made file: no Leap retargeting drives the 1-body tool).
  const csv6File = path.join(TMP, 'bench6.csv');
  const r6 = spawnSync(path.join(BIN, 'godhand-bench'), ['--recording', REC2, '--quiet', '--poses', csv6File,
    '--hand-model', path.join(DEPLOY, 'models', 'hand6_right.pbtxt'), '--left-hand-model', path.join(DEPLOY, 'models', 'hand6_left.pbtxt')],
  { timeout: 120000, encoding: 'utf8' });
  check(r6.status === 0, `godhand-bench with the 6-body hands ran (${r6.status} ${r6.stderr.trim()})`);
  const one = path.join(TMP, 'one-body.csv');
  fs.writeFileSync(one, 'frame,hand,body,shape,radius,half_length,hx,hy,hz,px,py,pz,qw,qx,qy,qz\n' +
    [0, 1, 2].map((f) => `${f},tool,tool,capsule,0.01,0.05,0,0,0,${0.01 * f},0.1,0.3,0.70710678118654757,0,0.70710678118654757,0`).join('\n') + '\n');
  // godhand-bench's --mesh scene, with the --recording it was centred on: the same scale and
  // placement as the bench reports, drawn.
  const bunny = path.join(DEPLOY, 'meshes', 'stanford-bunny.obj');
  const meshCsv = path.join(TMP, 'bench-mesh.csv'), meshJson = path.join(TMP, 'bench-mesh.json');
  const rm = spawnSync(path.join(BIN, 'godhand-bench'), ['--recording', REC1, '--mesh', bunny + ':0.15', '--frames', '40', '--quiet',
    '--poses', meshCsv, '--json', meshJson], { timeout: 120000, encoding: 'utf8' });
  check(rm.status === 0, `godhand-bench --mesh ran (${rm.status})`);
  const vm = await startViewer(['--poses', meshCsv, '--mesh', bunny + ':0.15', '--recording', REC1]);
  const off = await (await fetch(vm.url + 'offline.json')).json();
  const bj = JSON.parse(fs.readFileSync(meshJson, 'utf8'));
  const o = off.scene.objects;
  check(o.length === 1 && bj.meshes && Math.abs(o[0].scale - bj.meshes[0].scale) < 1e-12,
    `--mesh scene: one object at the bench's scale (${o.length && o[0].scale} vs ${bj.meshes && bj.meshes[0].scale})`);
  const pm = await openPage(vm.url);
  await pm.waitForFunction(() => window.godhand && window.godhand.scene && window.godhand.scene.meshes === 1, null, { timeout: 30000 });
  check(true, '--mesh scene drawn');
  await pm.close();
  await stop(vm.proc);

  for (const [file, hands, bodies] of [[csv6File, 2, 6], [one, 1, 1]]) {
    const c2 = readCsv(file);
    const v2 = await startViewer(['--poses', file]);
    const p2 = await openPage(v2.url);
    await p2.waitForFunction((n) => window.godhand && window.godhand.offline && Object.keys(window.godhand.drawn).length === n, hands, { timeout: 30000 });
    await p2.evaluate(() => window.godhand.showFrame(1));
    await p2.waitForFunction(() => Object.values(window.godhand.drawn).every((d) => d.frame === 1), null, { timeout: 10000 });
    const drawn = Object.values(await p2.evaluate(() => window.godhand.drawn));
    const errs = drawn.map((d) => poseError(d.poses, csvPoses(c2, 1, d.cluster)));
    check(drawn.length === hands && drawn.every((d) => d.poses.length === bodies) && errs.every((e) => e.pos < 1e-9 && e.rot < 1e-12),
      `${hands} hand(s) of ${bodies} bodies drawn at the file's poses (${path.basename(file)}: ${drawn.map((d) => d.cluster + ' ' + d.poses.length).join(', ')})`);
    check(p2.errors.length === 0, `no page errors (${p2.errors.slice(0, 3).join(' | ')})`);
    await p2.close();
    await stop(v2.proc);
  }
  await browser.close();
}

// A raw WebSocket client over TCP (RFC 6455 by hand: node 20 has no WebSocket client), so that
// it can send what no browser would and stop reading altogether.
function rawClient(port) {
  return new Promise((resolve, reject) => {
    const s = net.connect(port, '127.0.0.1');
    let buf = '';
    s.setTimeout(10000, () => { s.destroy(); reject(new Error('raw client timeout')); });
    s.on('error', reject);
    s.on('connect', () => s.write('GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n' +
      'Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.websocket.v1\r\n\r\n'));
    const onData = (d) => {
      buf += d.toString('latin1');
      if (buf.includes('\r\n\r\n')) { s.off('data', onData); s.setTimeout(0); resolve({ socket: s, status: buf.split(' ')[1] }); }
    };
    s.on('data', onData);
  });
}
function frame(opcode, payload) {
  const p = Buffer.isBuffer(payload) ? payload : Buffer.from(payload);
  const mask = Buffer.from([0x12, 0x34, 0x56, 0x78]);
  let head;
  if (p.length < 126) head = Buffer.from([0x80 | opcode, 0x80 | p.length]);
  else if (p.length < 65536) { head = Buffer.alloc(4); head[0] = 0x80 | opcode; head[1] = 0x80 | 126; head.writeUInt16BE(p.length, 2); }
  else { head = Buffer.alloc(10); head[0] = 0x80 | opcode; head[1] = 0x80 | 127; head.writeBigUInt64BE(BigInt(p.length), 2); }
  const body = Buffer.from(p.map((b, i) => b ^ mask[i % 4]));
  return Buffer.concat([head, mask, body]);
}

async function caseAbuse() {
  const v = await startViewer(['--domain', DOMAIN, '--max-queue-mb', '1']);
  await openBrowser();
  const page = await openPage(v.url);
  await page.waitForFunction(() => window.godhand && window.godhand.connected, null, { timeout: 20000 });
  // Speed 0.2: a 17 s replay, so that the 3 s window below still falls inside it after the abuse's
  // set-up (in CI at 0.35, a 10 s replay, the window once began after the replay had ended: 0 states).
  const l = launch(['--recording', REC2, '--speed', '0.2']);
  let replayOver = false;
  l.done.then(() => { replayOver = true; });
  await page.waitForFunction(() => window.godhand.received.hand_state > 20, null, { timeout: 60000 });
  // 1. A client that subscribes to everything (63 times over) and never reads.
  const stuck = await rawClient(v.port);
  check(stuck.status === '101', `raw WebSocket handshake accepted (${stuck.status})`);
  const subs = [];
  for (let i = 0; i < 63; i++) subs.push({ id: i + 1, channelId: (i % 7) + 1 });
  stuck.socket.write(frame(1, JSON.stringify({ op: 'subscribe', subscriptions: subs })));
  stuck.socket.pause();
  // 2. Malformed messages and an oversized frame from raw clients.
  const junk = await rawClient(v.port);
  for (const m of ['not json', '{"op":"subscribe","subscriptions":"x"}', '{"op":"nope"}', '[]']) junk.socket.write(frame(1, m));
  junk.socket.write(frame(2, Buffer.from([9, 9, 9])));
  junk.socket.write(frame(2, Buffer.from([1, 7, 0, 0, 0, 0x7b, 0x7d])));  // publish on a channel never advertised
  const big = await rawClient(v.port);
  big.socket.write(frame(1, 'x'.repeat(200 * 1024)));  // over the 64 KB limit: the server closes it
  const bigClosed = new Promise((r) => { big.socket.on('close', () => r(true)); setTimeout(() => r(false), 5000); });
  big.socket.resume();
  // Garbage HTTP and a path outside the page.
  const g = net.connect(v.port, '127.0.0.1');
  g.on('error', () => {});
  g.write('\x00\x01garbage\r\n\r\n');
  // A handshake of a WebSocket draft before RFC 6455 (hixie-76 / hybi-00: no version header),
  // whose reader in websocketpp has no message size limit: refused (a client that never ended a
  // message grew the viewer by 1 MB per MB sent).
  const oldProto = await new Promise((resolve) => {
    const s = net.connect(v.port, '127.0.0.1');
    let b = '';
    s.on('error', () => resolve('error'));
    s.on('data', (d) => { b += d.toString('latin1'); if (b.includes('\r\n')) { s.destroy(); resolve(b.split(' ')[1]); } });
    s.on('connect', () => s.write('GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: WebSocket\r\nConnection: Upgrade\r\n' +
      'Sec-WebSocket-Key1: 4 @1  46546xW%0l 1 5\r\nSec-WebSocket-Key2: 12998 5 Y3 1  .P00\r\n\r\n^n:ds[4U'));
    setTimeout(() => resolve('timeout'), 5000);
  });
  check(oldProto === '400', `a pre-RFC 6455 (hybi-00) handshake is refused (${oldProto})`);
  // RFC 6455 handshakes whose key is not 16 bytes of base64: refused with 400; the valid key of
  // the RFC's example is answered 101 (the same request otherwise).
  const handshake = (key) => new Promise((resolve) => {
    const s = net.connect(v.port, '127.0.0.1');
    let b = '';
    s.on('error', () => resolve('error'));
    s.on('data', (d) => { b += d.toString('latin1'); if (b.includes('\r\n')) { s.destroy(); resolve(b.split(' ')[1]); } });
    s.on('connect', () => s.write('GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n' +
      `Sec-WebSocket-Key: ${key}\r\nSec-WebSocket-Version: 13\r\n\r\n`));
    setTimeout(() => resolve('timeout'), 5000);
  });
  const keys = { good: 'dGhlIHNhbXBsZSBub25jZQ==', short: 'abc', long: 'x'.repeat(4000), notBase64: 'dGhlIHNhbXBsZSBub25j*Q==',
    badPadding: 'dGhlIHNhbXBsZSBub25jZR==' };
  const answers = {};
  for (const [name, key] of Object.entries(keys)) answers[name] = await handshake(key);
  check(answers.good === '101' && answers.short === '400' && answers.long === '400' && answers.notBase64 === '400' &&
    answers.badPadding === '400', `Sec-WebSocket-Key checked: ${JSON.stringify(answers)}`);
  const escape = await fetch(v.url + '../../../etc/passwd').then((x) => x.status).catch(() => 0);
  const escape2 = await fetch(v.url + 'mesh/..%2f..%2fetc%2fpasswd').then((x) => x.status).catch(() => 0);
  // 3. Twenty clients from the browser connecting, subscribing and leaving.
  const churn = await page.evaluate(async (url) => {
    let opened = 0;
    for (let i = 0; i < 20; i++) {
      await new Promise((resolve) => {
        const ws = new WebSocket(url, ['foxglove.websocket.v1']);
        ws.onopen = () => { opened++; ws.send(JSON.stringify({ op: 'subscribe', subscriptions: [{ id: 1, channelId: 1 }] })); setTimeout(() => { ws.close(); resolve(); }, 50); };
        ws.onerror = () => resolve();
      });
    }
    return opened;
  }, v.url.replace('http', 'ws'));
  check(churn === 20, `20 clients connected and left (${churn} opened)`);
  check(await bigClosed, 'a 200 KB frame (over the 64 KB limit) closes that connection only');
  check(escape === 404 && escape2 === 404, `paths outside the page are not served (${escape}, ${escape2})`);
  // The page against the viewer's own count (viewer_stats, sent every 0.5 s, so up to 0.5 s old)
  // over the same 3 s; that it lost none is the per-connection count below.
  const count = () => page.evaluate(() => [window.godhand.received.hand_state, window.godhand.viewerStats ? window.godhand.viewerStats.received.hand_state : 0]);
  const before = await count();
  await sleep(3000);
  const after = await count();
  const dPage = after[0] - before[0], dViewer = after[1] - before[1];
  check(!replayOver, 'the 3 s window fell inside the replay (else it measures nothing)');
  check(dViewer > 5 && dPage >= 0.6 * dViewer,
    `the real page kept receiving during the abuse: ${dPage} HandStates in 3 s, the viewer took ${dViewer} from DDS`);
  // The never-reading client's messages are dropped once its 1 MB queue is full, which is after
  // the kernel's socket buffers (here up to 32 MB: net.ipv4.tcp_rmem) took what they could: wait
  // for the first drop while the replay runs. With the page that drew continuously (and slowed
  // every step here) 3,056 had been dropped by this point; with the page that draws on demand, 0.
  let s = await stats(v.url);
  for (const deadline = Date.now() + 15000; s.dropped === 0 && !replayOver && Date.now() < deadline; s = await stats(v.url)) await sleep(250);
  check(s.dropped > 0, `messages for the never-reading client were dropped and counted (${s.dropped})`);
  // The page's own connection: the other clients' abuse costs it nothing. A page that falls more
  // than 128 messages behind (busy drawing on a loaded machine: 51 of 717 once under ctest -j2)
  // skips older messages for the newest of each hand, every one counted as superseded; nothing
  // else is dropped for it.
  const pageId = await page.evaluate(() => window.godhand.feed.sessionId);
  const pageClient = s.per_client.find((c) => c.id === pageId);
  check(!!pageClient && pageClient.sent > 50 && pageClient.dropped === pageClient.superseded && pageClient.rejected === 0,
    `the page's connection lost nothing but older messages superseded while it was behind (sent, dropped, superseded: ${
      JSON.stringify(s.per_client.map((c) => [c.id === pageId ? 'page' : c.id, c.sent, c.dropped, c.superseded]))})`);
  // The page shows what its own connection skipped (it finds itself in viewer_stats by session id;
  // viewer_stats comes every 0.5 s, so its figure may be a little older than /stats.json's).
  const skipped = await page.evaluate(() => [...document.querySelectorAll('#figures tr')].map((r) => r.textContent)
    .find((t) => t.startsWith('skipped for this page')));
  const shown = /^skipped for this page \(it fell behind\)(\d+)$/.exec(skipped || '');
  check(!!shown && pageClient && Number(shown[1]) <= pageClient.superseded,
    `the page shows what it skipped (${skipped}; the viewer counted ${pageClient ? pageClient.superseded : '?'})`);
  check(s.rejected >= 6, `malformed client messages counted (${s.rejected})`);
  check(s.opened >= 24, `connections opened ${s.opened}, closed ${s.closed}`);
  const r = await l.done;
  const j = r.json;
  check(r.code === 0 && j.clean_shutdown === true, `the services ran to the end and stopped cleanly while the viewer was abused (${r.code})`);
  // The method's guarantee (METHOD §5, godhand-launch --check): no penetration beyond the contact
  // margin. Live, Bullet moves dynamic objects into God objects, which the scene pushes out in the
  // same step: 0.137 mm (light_box in the right palm) failed this check in CI on 2026-12-01, when
  // the push-out read a box core crossing the cube's corner as touching (fixed 2026-12-02).
  check(j.penetration_max_m <= j.margin_m && j.margin_m > 0 && j.solver_failures === 0,
    `no penetration beyond the ${j.margin_m * 1e3} mm margin, no solver failure (${j.penetration_max_m} m, ${j.solver_failures})`);
  const s2 = j.services || {};
  check(Object.values(s2).every((x) => !x.rejected), `no service rejected a sample (${Object.entries(s2).map(([k, x]) => k + ' ' + x.rejected).join(', ')})`);
  console.log(`figure: services during the abuse: ${j.frames} of ${j.expected_frames} frames fresh in every cluster, ${j.frames_per_s && j.frames_per_s.toFixed(1)} frames/s, ` +
    `latency median ${(j.latency_us.median / 1000).toFixed(2)} ms p99 ${(j.latency_us.p99 / 1000).toFixed(2)} ms`);
  stuck.socket.destroy();
  junk.socket.destroy();
  g.destroy();
  const fin = await stats(v.url).catch(() => null);
  check(fin !== null, 'the viewer still answers after the run');
  check(page.errors.length === 0, `no page errors (${page.errors.slice(0, 3).join(' | ')})`);
  await browser.close();
  const vr = await stop(v.proc);
  check(vr.code === 0, `godhand-viewer stopped cleanly (${vr.code})`);
  console.log(v.proc.err.trim().split('\n').slice(-1)[0]);
}

// No tracker: the page drives the right hand (godhand-viewer --synthetic right) while the services
// run with a silent live tracker source. Pressing Q moves the target down into the bunny: the God
// hand follows, then stops on the surface (no penetration) while its target goes on down.
async function caseSynthetic() {
  const v = await startViewer(['--domain', DOMAIN, '--synthetic', 'right']);
  await openBrowser();
  const page = await openPage(v.url);
  await page.waitForFunction(() => window.godhand && window.godhand.connected, null, { timeout: 20000 });
  const udp = 20000 + Number(DOMAIN);
  const l = launch(['--source', `dtrack://127.0.0.1:${udp}`, '--duration', '15']);
  await page.waitForFunction(() => window.godhand.drawn[0] && !window.godhand.drawn[0].stale && window.godhand.drawn[0].frame > 20, null, { timeout: 60000 });
  const at = async () => page.evaluate(() => { const d = window.godhand.drawn[0]; const s = document.getElementById('hand-0');
    return { z: d.poses[0][2], tz: d.ghost[0][2], frame: d.frame, text: s ? s.textContent : '', states: window.godhand.received.hand_state,
      sent: window.godhand.synthetic.sent, stale: d.stale, held: d.held }; });
  // Where the loop page -> viewer -> services -> viewer -> page stood (for a failure's message).
  const loop = (a) => `drawn frame ${a.frame}, HandStates received ${a.states}, synthetic commands sent ${a.sent}${a.stale ? ', stale' : ''}${a.held ? ', held' : ''} (${a.text.replace(/\s+/g, ' ').slice(0, 160)})`;
  const start = await at();
  check(true, `the synthetic right hand is drawn (palm at z ${start.z.toFixed(3)} m, target z ${start.tz.toFixed(3)} m)`);
  // The page moves its offset at 6 cm/s of its own clock, which a loaded machine starves (seen in
  // CI: 600 ms of E moved nothing), and the target comes back through the services: each key is
  // held until the page's offset has moved as far as the test needs, then the test waits until
  // the drawn target is where that offset puts it (and, going up in free space, the God hand
  // with it); deadlines 20 s each.
  const offsetZ = () => page.evaluate(() => window.godhand.synthetic.offset.z);
  const hold = async (key, done) => {
    await page.keyboard.down(key);
    const t = Date.now();
    while (!done(await offsetZ()) && Date.now() - t < 20000) await sleep(50);
    await page.keyboard.up(key);
  };
  const settle = async (done) => {
    const t = Date.now();
    for (;;) {
      const a = await at();
      const oz = await offsetZ();
      if ((Math.abs(a.tz - (start.tz + oz)) < 1e-3 && done(a)) || Date.now() - t > 20000) return a;
      await sleep(100);
    }
  };
  await hold('e', (oz) => oz >= 0.036);
  const up = await settle((a) => Math.abs(a.z - a.tz) < 0.005);
  check(up.tz > start.tz + 0.01 && up.z > start.z + 0.01, `E moved the target and the God hand up (target ${start.tz.toFixed(3)} -> ${up.tz.toFixed(3)}, God ${start.z.toFixed(3)} -> ${up.z.toFixed(3)}; at start ${loop(start)}; now ${loop(up)})`);
  await hold('q', (oz) => oz <= -0.204);
  await sleep(800);  // the God hand's last steps towards the bunny
  const down = await settle(() => true);
  // (The God hand must have come down towards the bunny too: a hand that never moved is above it.)
  check(down.tz < down.z - 0.02 && down.z < up.z - 0.05,
    `Q pushed the target into the bunny (target z ${down.tz.toFixed(3)} m) and the God hand came down (${up.z.toFixed(3)} -> ${down.z.toFixed(3)} m) and stopped above it; ${loop(down)}`);
  const rec = await page.evaluate(() => window.godhand.synthetic.sent);
  check(rec > 10, `the page sent ${rec} synthetic commands`);
  const penPage = await page.evaluate(() => window.godhand.drawn[0].penetrationMax);
  await stop(l);
  const r = await l.done;
  // The viewer's penetration figure against the launcher's own monitor (same states, same scene).
  const penLaunch = r.json.penetration_max_m;
  check(typeof penPage === 'number' && typeof penLaunch === 'number' && Math.abs(penPage - penLaunch) < 2e-5,
    `the page's penetration figure (max ${(1000 * penPage).toFixed(3)} mm) agrees with the launcher's monitor (${(1000 * penLaunch).toFixed(3)} mm)`);
  console.log(`figure: penetration while pushing the synthetic hand into the bunny: ${(1000 * penLaunch).toFixed(3)} mm (margin 0.1 mm)`);
  // The method's guarantee while a hand is pushed deep into a static mesh (0.74-0.85 mm was
  // measured here in an earlier tree; 0.000 mm in 3 of 3 runs on 2026-12-02).
  check(typeof penLaunch === 'number' && penLaunch <= r.json.margin_m,
    `no penetration beyond the ${(1000 * r.json.margin_m).toFixed(1)} mm margin while pushed into the bunny (${(1000 * penLaunch).toFixed(3)} mm)`);
  check(page.errors.length === 0, `no page errors (${page.errors.slice(0, 3).join(' | ')})`);
  await browser.close();
  const vr = await stop(v.proc);
  check(vr.code === 0, `godhand-viewer stopped cleanly (${vr.code})`);
  console.log(v.proc.err.trim().split('\n').slice(-1)[0]);
}

// The README's picture: the live page on the bundled two-hand recording, taken when both hands
// are fresh and in contact, drawn as on a GPU (antialiased, full resolution and detail;
// OUT=file.png; not a test).
async function caseScreenshot() {
  const out = process.env.OUT || path.join(TMP, 'viewer.png');
  const v = await startViewer(['--domain', DOMAIN]);
  await openBrowser();
  const page = await openPage(v.url + '?aa=1&scale=1&detail=full', { width: 1280, height: 760 });
  await page.waitForFunction(() => window.godhand && window.godhand.connected, null, { timeout: 20000 });
  const l = launch(['--recording', REC2, '--speed', '0.25']);
  let best = -1;
  let ended = false;
  l.done.then(() => { ended = true; });
  while (!ended) {
    const d = await page.evaluate(() => ({ n: Object.values(window.godhand.drawn).filter((x) => !x.stale && !x.held && x.ghostVisible).length, c: window.godhand.contacts }));
    if (d.n === 2 && d.c > best) {
      best = d.c;
      await page.screenshot({ path: out });
    }
    await sleep(250);
  }
  check(best >= 0, `screenshot with both hands fresh and ${best} contacts: ${out}`);
  await browser.close();
  await stop(v.proc);
}

// A reading raw client: HandState JSON taken by the viewer (recv_ns) -> arrived here, in ms; no
// browser main thread in the way, so this is the viewer's own added delay (plus the socket's).
async function rawReader(port) {
  const c = await rawClient(port);
  const delays = [];
  let buf = Buffer.alloc(0);
  c.socket.on('data', (d) => {
    buf = Buffer.concat([buf, d]);
    for (;;) {
      if (buf.length < 2) return;
      let len = buf[1] & 0x7f, off = 2;
      if (len === 126) { if (buf.length < 4) return; len = buf.readUInt16BE(2); off = 4; }
      else if (len === 127) { if (buf.length < 10) return; len = Number(buf.readBigUInt64BE(2)); off = 10; }
      if (buf.length < off + len) return;
      const op = buf[0] & 0x0f, payload = buf.subarray(off, off + len);
      buf = buf.subarray(off + len);
      if (op === 2 && payload[0] === 1) {
        const m = JSON.parse(payload.subarray(13).toString('utf8'));
        if (m.recv_ns) delays.push((performance.timeOrigin + performance.now()) - m.recv_ns / 1e6);
      }
    }
  });
  c.socket.write(frame(1, JSON.stringify({ op: 'subscribe', subscriptions: [{ id: 1, channelId: 1 }] })));
  return { delays, close: () => c.socket.destroy() };
}

// The browser's CPU: every chromium process under this test (browser, GPU process, where
// software WebGL draws, renderers, utilities): pid -> utime + stime in seconds. cpuSince(a, b):
// what the processes alive at b spent since a (a renderer closed in between takes its time along).
function browserCpu() {
  const parent = new Map(), comm = new Map();
  for (const d of fs.readdirSync('/proc')) {
    if (!/^\d+$/.test(d)) continue;
    try {
      const st = fs.readFileSync(`/proc/${d}/stat`, 'utf8');
      parent.set(Number(d), Number(st.slice(st.lastIndexOf(')') + 2).split(' ')[1]));
      comm.set(Number(d), st.slice(st.indexOf('(') + 1, st.lastIndexOf(')')));
    } catch { /* gone */ }
  }
  const under = (pid) => { for (let p = parent.get(pid); p; p = parent.get(p)) if (p === process.pid) return true; return false; };
  const out = new Map();
  for (const [pid, c] of comm) if (/chrom/i.test(c) && under(pid)) out.set(pid, cpuSeconds(pid) || 0);
  return out;
}
const cpuSince = (a, b) => [...b].reduce((s, [pid, x]) => s + x - (a.get(pid) || 0), 0);
// Per thread of every chromium process under this test: 'type:thread' -> CPU seconds.
function browserThreads() {
  const out = new Map();
  for (const d of fs.readdirSync('/proc')) {
    if (!/^\d+$/.test(d)) continue;
    try {
      const comm = fs.readFileSync(`/proc/${d}/comm`, 'utf8').trim();
      if (!/chrom/i.test(comm)) continue;
      const cmd = fs.readFileSync(`/proc/${d}/cmdline`, 'utf8');
      const type = (cmd.match(/--type=([a-z-]+)/) || [null, 'browser'])[1];
      for (const t of fs.readdirSync(`/proc/${d}/task`)) {
        const st = fs.readFileSync(`/proc/${d}/task/${t}/stat`, 'utf8');
        const name = st.slice(st.indexOf('(') + 1, st.lastIndexOf(')'));
        const parts = st.slice(st.lastIndexOf(')') + 2).split(' ');
        const k = `${type}:${name}`;
        out.set(k, (out.get(k) || 0) + (Number(parts[11]) + Number(parts[12])) / 100);
      }
    } catch { /* gone */ }
  }
  return out;
}
// A page's own main-thread time (CDP Performance.getMetrics: TaskDuration, ScriptDuration, in s)
// and how many frames it drew; meter.take() gives each per second since the previous take().
async function pageMeter(page) {
  const cdp = await page.context().newCDPSession(page);
  await cdp.send('Performance.enable');
  const read = async () => {
    const m = Object.fromEntries((await cdp.send('Performance.getMetrics')).metrics.map((x) => [x.name, x.value]));
    const g = await page.evaluate(() => ({ renders: window.godhand.renders, cost: window.godhand.cost || {},
      info: window.godhand.renderInfo ? window.godhand.renderInfo() : {} }));
    return { t: m.Timestamp, task: m.TaskDuration, script: m.ScriptDuration, ...g };
  };
  let last = await read();
  return {
    async take() {
      const now = await read(), dt = now.t - last.t;
      const r = { task: (now.task - last.task) / dt, script: (now.script - last.script) / dt, fps: (now.renders - last.renders) / dt,
        cost: Object.fromEntries(Object.keys(now.cost).map((k) => [k, (now.cost[k] - last.cost[k]) / 1000 / dt])), info: now.info };
      last = now;
      return r;
    },
  };
}
const sum = (a, k) => a.reduce((s, x) => s + x[k], 0);
const pctOf = (x) => `${(100 * x).toFixed(1)} %`;
function pagesFigure(per, browserCpu) {
  if (!per.length) return `browser (no page) ${pctOf(browserCpu)} of a core`;
  return `pages' main threads ${per.map((x) => pctOf(x.task)).join(', ')} of a core (script ${pctOf(sum(per, 'script') / per.length)} each), ` +
    `${(sum(per, 'fps') / per.length).toFixed(1)} frames/s each; the whole browser ${pctOf(browserCpu)} of a core`;
}

// Services' latency with 0 and PAGES (5) pages open, alternated, RUNS (3) runs each; per run the
// viewer's CPU, each page's own CPU and frame rate and the whole browser's CPU. WEB_ROOT=DIR serves
// another build of the page (e.g. an earlier one) to compare.
async function caseMeasure() {
  const runs = Number(process.env.RUNS || 3), npages = Number(process.env.PAGES || 5);
  const v = await startViewer(['--domain', DOMAIN, ...(process.env.WEB_ROOT ? ['--web-root', process.env.WEB_ROOT] : [])]);
  const reader = await rawReader(v.port);
  await openBrowser();
  const results = { 0: [], [npages]: [] };
  let pages = [];
  console.log(`load before: ${os.loadavg().map((x) => x.toFixed(2)).join(' ')}; browsers: nice ${process.env.BROWSER_NICE || 0}` +
    `${process.env.BROWSER_SCHED ? ', SCHED_' + process.env.BROWSER_SCHED.toUpperCase() : ''}; page ${process.env.PAGE_QUERY || '(defaults)'}`);
  for (let i = 0; i < runs; i++) {
    for (const n of [0, npages]) {
      while (pages.length < n) { pages.push(await openPage(v.url + (process.env.PAGE_QUERY || ''), { width: 800, height: 600 })); }
      while (pages.length > n) await pages.pop().close();
      for (const p of pages) await p.waitForFunction(() => window.godhand && window.godhand.connected, null, { timeout: 20000 });
      for (const p of pages) await p.evaluate(() => { window.godhand.latenciesMs.length = 0; window.godhand.endToEndMs.length = 0; window.godhand.arrivalMs.length = 0; });
      const meters = [];
      for (const p of pages) meters.push(await pageMeter(p));
      const cpu0 = cpuSeconds(v.proc.pid), b0 = browserCpu(), t0 = Date.now();
      const r = await launch(['--recording', REC2]).done;
      const dt = (Date.now() - t0) / 1000;
      const cpu = (cpuSeconds(v.proc.pid) - cpu0) / dt, bcpu = cpuSince(b0, browserCpu()) / dt;
      const per = [];
      for (const m of meters) per.push(await m.take());
      const lat = r.json.latency_us || {};
      const pl = [];
      const pa = [];
      for (const p of pages) pl.push(...(await p.evaluate(() => window.godhand.latenciesMs.slice(3))));
      for (const p of pages) pa.push(...(await p.evaluate(() => window.godhand.arrivalMs.slice(3))));
      results[n].push({ median: lat.median, p99: lat.p99, cpu, viewer_median: median(pl), viewer_p99: pct(pl, 0.99) });
      console.log(`figure: browsers ${n}: services latency median ${(lat.median / 1000).toFixed(2)} ms p99 ${(lat.p99 / 1000).toFixed(2)} ms; ` +
        `viewer CPU ${(100 * cpu).toFixed(1)} % of a core; viewer->page median ${median(pa).toFixed(2)} ms p99 ${pct(pa, 0.99).toFixed(2)} ms; ` +
        `viewer->drawn median ${median(pl).toFixed(1)} ms p99 ${pct(pl, 0.99).toFixed(1)} ms; ${pagesFigure(per, bcpu)} (${dt.toFixed(1)} s run)`);
    }
  }
  const d = reader.delays.slice(5);
  console.log(`figure: viewer's own delay (HandState taken from DDS -> arrived at a reading raw WebSocket client): median ${median(d).toFixed(2)} ms, p99 ${pct(d, 0.99).toFixed(2)} ms over ${d.length} states`);
  reader.close();
  for (const n of [0, npages]) {
    const m = results[n].map((x) => x.median / 1000), p = results[n].map((x) => x.p99 / 1000);
    console.log(`summary: browsers ${n}: services latency median over runs ${m.map((x) => x.toFixed(2)).join(', ')} ms; p99 ${p.map((x) => x.toFixed(2)).join(', ')} ms`);
  }
  console.log(`load after: ${os.loadavg().map((x) => x.toFixed(2)).join(' ')}`);
  await browser.close();
  await stop(v.proc);
  check(true, 'figures printed');
}

// What a page costs (figures, not a pass/fail test): PAGES (1) pages on a live replay at --speed
// SPEED (0.25: the recording's 48.5 Hz hands at 12 Hz for ~15 s), WINDOW_MS (8000) measured in
// its middle, then 5 s with nothing arriving; CPU per thread. WEB_ROOT=DIR: another build of the
// page; PAGE_QUERY, VIEWER_ARGS.
async function caseCost() {
  const npages = Number(process.env.PAGES || 1), speed = process.env.SPEED || '0.25';
  const v = await startViewer(['--domain', DOMAIN, ...(process.env.WEB_ROOT ? ['--web-root', process.env.WEB_ROOT] : []), ...(process.env.VIEWER_ARGS ? process.env.VIEWER_ARGS.split(' ') : [])]);
  await openBrowser();
  const pages = [];
  for (let i = 0; i < npages; i++) pages.push(await openPage(v.url + (process.env.PAGE_QUERY || ''), { width: 800, height: 600 }));
  for (const p of pages) await p.waitForFunction(() => window.godhand && window.godhand.connected, null, { timeout: 20000 });
  const l = launch(['--recording', REC2, '--speed', speed]);
  await pages[0].waitForFunction(() => window.godhand.received.hand_state > 40, null, { timeout: 60000 });
  await sleep(1000);
  const measure = async (ms) => {
    const meters = [];
    for (const p of pages) meters.push(await pageMeter(p));
    const th0 = browserThreads();
    const b0 = browserCpu(), t0 = Date.now(), s0 = await pages[0].evaluate(() => window.godhand.received.hand_state);
    await sleep(ms);
    const dt = (Date.now() - t0) / 1000, bcpu = cpuSince(b0, browserCpu()) / dt;
    const th = [...browserThreads()].map(([k, x]) => [k, (x - (th0.get(k) || 0)) / dt]).filter(([, x]) => x > 0.005).sort((a, b) => b[1] - a[1]);
    console.log('threads: ' + th.map(([k, x]) => `${k} ${pctOf(x)}`).join(', '));
    const states = ((await pages[0].evaluate(() => window.godhand.received.hand_state)) - s0) / dt;
    const per = [];
    for (const m of meters) per.push(await m.take());
    return { per, bcpu, states };
  };
  const live = await measure(Number(process.env.WINDOW_MS || 8000));
  console.log(`figure: live (${live.states.toFixed(1)} HandStates/s): ${pagesFigure(live.per, live.bcpu)}`);
  console.log(`renderer: ${await pages[0].evaluate(() => { const gl = document.querySelector('#view canvas').getContext('webgl2'); const e = gl.getExtension('WEBGL_debug_renderer_info'); return e ? gl.getParameter(e.UNMASKED_RENDERER_WEBGL) : '?'; })}`);
  const c = live.per[0];
  console.log(`figure: the first page's own counters: ${Object.entries(c.cost).map(([k, x]) => `${k} ${pctOf(x)}`).join(', ')} of a core; ` +
    `a frame: ${JSON.stringify(c.info)}`);
  const r = await l.done;
  check(r.code === 0, `the replay ran (${r.code})`);
  await sleep(1000);
  const idle = await measure(5000);
  console.log(`figure: nothing arriving: ${pagesFigure(idle.per, idle.bcpu)}`);
  console.log(`load: ${os.loadavg().map((x) => x.toFixed(2)).join(' ')}`);
  await browser.close();
  await stop(v.proc);
}

// Fast DDS segments that appeared during the test and that nobody holds any more (their _el lock
// is free), as godhand-launch counts them. Polled for up to 3 s (a participant closing takes a moment).
const SHM_BEFORE = new Set(fs.readdirSync('/dev/shm').filter((n) => n.includes('fastrtps')));
async function leftoverShm() {
  const py = `import fcntl, os, sys
before = set(sys.argv[1:])
out = []
for n in os.listdir('/dev/shm'):
    if 'fastrtps' not in n or n.endswith('_el') or n in before:
        continue
    try:
        fd = os.open('/dev/shm/' + n + '_el', os.O_RDWR)
    except OSError:
        continue
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        out.append(n)
    except OSError:
        pass
    finally:
        os.close(fd)
print(' '.join(out))`;
  let names = [];
  for (let i = 0; i < 6; i++) {
    const r = spawnSync('python3', ['-c', py, ...SHM_BEFORE], { encoding: 'utf8', timeout: 10000 });
    names = (r.stdout || '').trim().split(/\s+/).filter(Boolean);
    if (!names.length) break;
    await sleep(500);
  }
  return names;
}

const CASES = { live: caseLive, poses: casePoses, offline: caseOffline, abuse: caseAbuse, synthetic: caseSynthetic, screenshot: caseScreenshot, measure: caseMeasure, cost: caseCost };
if (!CASES[CASE]) { console.log(`unknown case ${CASE}`); process.exit(2); }
const LIMIT_S = CASE === 'measure' || CASE === 'cost' ? 590 : 170;
const watchdog = setTimeout(() => { console.log(`FAILED: the case took longer than ${LIMIT_S} s`); cleanup().then(() => process.exit(1)); }, LIMIT_S * 1000);
async function cleanup() {
  if (browser) await browser.close().catch(() => {});
  for (const p of children) await stop(p, 3000);
}
try {
  await CASES[CASE]();
} catch (e) {
  failures.push(String(e && e.stack || e));
  console.log('FAILED: ' + (e && e.stack || e));
  for (const p of children) if (p.err) console.log(`--- ${p.name} stderr (tail)\n` + p.err.slice(-2000));
}
await cleanup();
clearTimeout(watchdog);
// Nothing of this domain left running.
const shmLeft = await leftoverShm();
check(shmLeft.length === 0, `no Fast DDS shared-memory segment of this test left unlocked (${shmLeft.join(' ')})`);
const left = spawnSync('pgrep', ['-af', 'godhand-'], { encoding: 'utf8' }).stdout.split('\n').filter((x) => x.includes(`--domain ${DOMAIN} `) || x.endsWith(`--domain ${DOMAIN}`));
check(left.length === 0, `no process of domain ${DOMAIN} left (${left.join('; ')})`);
if (failures.length === 0) fs.rmSync(TMP, { recursive: true, force: true });
else console.log(`kept ${TMP}`);
console.log(failures.length ? `FAILED: ${failures.length} check(s)` : 'PASSED');
process.exit(failures.length ? 1 : 0);
