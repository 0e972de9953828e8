// The viewer of zipfusion's live stream: one WebSocket to /stream on the page's own server; each
// binary message is a frame ("ZFM1", header length, JSON header, Draco mesh), decoded by three.js's
// DRACOLoader in its workers and drawn. The first (text) message describes the stream: frame rate,
// cameras (the "view" choices) and the capture volume.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { DRACOLoader } from 'three/examples/jsm/loaders/DRACOLoader.js';

const $ = (id) => document.getElementById(id);

// --- scene -----------------------------------------------------------------------------------
const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(window.innerWidth, window.innerHeight);
$('view').appendChild(renderer.domElement);

const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1b1d22);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404048, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.2);
sun.position.set(2, -3, 4);
scene.add(sun);

// The capture's world is z-up (the floor at z = 0).
const camera = new THREE.PerspectiveCamera(45, window.innerWidth / window.innerHeight, 0.05, 50);
camera.up.set(0, 0, 1);
camera.position.set(0, -3.2, 1.4);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0, 0, 0.9);
controls.update();

const grid = new THREE.GridHelper(4, 8, 0x3a3f48, 0x2b2f36);
grid.rotation.x = Math.PI / 2;  // into the z = 0 plane
scene.add(grid);

const coloured = new THREE.MeshBasicMaterial({ vertexColors: true, side: THREE.DoubleSide });
const shaded = new THREE.MeshStandardMaterial({ color: 0xb9bcc4, roughness: 0.8, side: THREE.DoubleSide, flatShading: true });
const mesh = new THREE.Mesh(new THREE.BufferGeometry(), coloured);
scene.add(mesh);

function applyMaterial() {
  mesh.material = $('color').checked ? coloured : shaded;
  coloured.wireframe = shaded.wireframe = $('wireframe').checked;
}
$('color').addEventListener('change', applyMaterial);
$('wireframe').addEventListener('change', applyMaterial);

window.addEventListener('resize', () => {
  renderer.setSize(window.innerWidth, window.innerHeight);
  if ($('viewpoint').value === 'free') {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
  }
});

// --- views from each camera --------------------------------------------------------------------
let cameras = [];

// A capture camera's pose as the three.js camera: its axes are OpenCV's (x right, y down, z
// forward), three.js looks down −z with y up, so the pose turns half a turn about x.
function lookThrough(model) {
  const m = model.world_from_depth;
  const world = new THREE.Matrix4().set(...m[0], ...m[1], ...m[2], ...m[3]);
  const flip = new THREE.Matrix4().makeRotationX(Math.PI);
  world.multiply(flip);
  world.decompose(camera.position, camera.quaternion, new THREE.Vector3());
  const k = model.intrinsics;
  camera.fov = THREE.MathUtils.radToDeg(2 * Math.atan(k.height / 2 / k.fy));
  camera.aspect = k.width / k.height;
  camera.updateProjectionMatrix();
}

$('viewpoint').addEventListener('change', () => {
  const choice = $('viewpoint').value;
  controls.enabled = choice === 'free';
  if (choice === 'free') {
    camera.up.set(0, 0, 1);
    camera.position.set(0, -3.2, 1.4);
    camera.fov = 45;
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
    controls.target.set(0, 0, 0.9);
    controls.update();
  } else {
    lookThrough(cameras[Number(choice)]);
  }
});

// --- statistics ------------------------------------------------------------------------------
const drawnTimes = [];     // performance.now() of the last frames drawn
const latencies = [];      // ms, capture → drawn, of the last frames
const received = [];       // [performance.now(), bytes] of the last messages
function median(values) {
  if (values.length === 0) return NaN;
  const sorted = [...values].sort((a, b) => a - b);
  return sorted[Math.floor(sorted.length / 2)];
}
// Appends to a list of the last `keep` values.
function pushLast(list, value, keep) {
  list.push(value);
  if (list.length > keep) list.shift();
}
function trim(list, keepMs, now, at = (x) => x) {
  while (list.length > 0 && now - at(list[0]) > keepMs) list.shift();
}
function showStats() {
  const now = performance.now();
  trim(drawnTimes, 2000, now);
  trim(received, 2000, now, (x) => x[0]);
  const span = drawnTimes.length > 1 ? drawnTimes[drawnTimes.length - 1] - drawnTimes[0] : 0;
  $('fps').textContent = span > 0 ? ((drawnTimes.length - 1) * 1000 / span).toFixed(1) : '0.0';
  const bytes = received.reduce((sum, r) => sum + r[1], 0);
  const window_ms = received.length > 1 ? Math.max(now - received[0][0], 1) : 1000;
  $('bitrate').textContent = `${(bytes * 8 / window_ms / 1000).toFixed(1)} Mbit/s`;
  const lat = median(latencies);
  $('latency').textContent = Number.isFinite(lat) ? `${lat.toFixed(0)} ms` : '–';
}
setInterval(showStats, 250);

// --- the stream ------------------------------------------------------------------------------
const draco = new DRACOLoader();
draco.setDecoderPath('draco/');
draco.setWorkerLimit(2);

// Flow control: every frame received is acknowledged once (when it is decoded or drawn, skipped
// for a newer one, or cannot be read), and the server keeps at most `flowWindow` unacknowledged,
// so a viewer slower than the stream gets the newest frame instead of a backlog in the network's
// buffers. The server makes a frame only when a viewer has room for it, so a frame's making
// (reconstruction, compression: tens of ms) is part of the loop from one acknowledgement to the
// next frame, and a viewer that keeps up needs several in flight to get every frame: with
// instant acknowledgements, one gives 16-19 frames/s of a 30 fps stream, two 29.5, three 30
// (zf_stream_clients --window). A viewer that draws fewer frames than the stream has (a browser
// drawing in software) gains little from more than one: a frame waits, ageing, while the one
// before is drawn. Such a viewer tries one, and goes back to the wide window if its frame rate
// halves (a long round trip, now between every two frames) or it keeps up with the stream
// again, then stays wide for 30 s.
const WIDE_WINDOW = 3;
let flowWindow = WIDE_WINDOW;
const drawPeriods = [];      // ms between the last frames drawn
const frameSteps = [];       // the stream's frame sets from one frame drawn to the next (1: none missed)
let lastDrawnSequence = null;
let periodWide = 0;          // the median draw period when the window went down to 1
let retryAt = 0;             // performance.now() before which the window stays wide
function acknowledge() {
  if (socket.readyState === WebSocket.OPEN) socket.send('{"type":"ack"}');
}
function setFlowWindow(n) {
  if (n === flowWindow || socket.readyState !== WebSocket.OPEN) return;
  flowWindow = n;
  drawPeriods.length = frameSteps.length = 0;
  socket.send(JSON.stringify({ type: 'flow', window: n }));
  document.body.dataset.flowWindow = String(n);
}
function adaptFlowWindow() {
  if (drawPeriods.length < 20 || frameSteps.length < 20 || paused || document.hidden) return;
  const drawn = median(drawPeriods);
  const framesPerDrawn = frameSteps.reduce((sum, s) => sum + s, 0) / frameSteps.length;
  if (flowWindow === WIDE_WINDOW && framesPerDrawn > 1.25 && performance.now() >= retryAt) {
    periodWide = drawn;
    setFlowWindow(1);
  } else if (flowWindow === 1 && (framesPerDrawn < 1.1 || drawn > 2 * periodWide)) {
    retryAt = performance.now() + 30000;
    setFlowWindow(WIDE_WINDOW);
  }
}
setInterval(adaptFlowWindow, 1000);

let paused = false;
let decoding = false;
let pending = null;  // the newest frame waiting while one decodes: older ones are skipped

function parseFrame(data) {
  const bytes = new Uint8Array(data);
  if (bytes.length < 8 || String.fromCharCode(...bytes.subarray(0, 4)) !== 'ZFM1') return null;
  const length = new DataView(data).getUint32(4, true);
  if (8 + length > bytes.length) return null;
  const header = JSON.parse(new TextDecoder().decode(bytes.subarray(8, 8 + length)));
  return { header, draco: data.slice(8 + length) };
}

function show(frame, geometry) {
  mesh.geometry.dispose();
  mesh.geometry = geometry;
  requestRedraw();
  if (!$('color').checked) geometry.computeVertexNormals();
  const h = frame.header;
  $('frame').textContent = h.frame;
  $('triangles').textContent = h.triangles.toLocaleString('en');
  $('reconstruct').textContent = `${h.reconstruct_ms.toFixed(1)} + ${h.encode_ms.toFixed(1)} ms`;
  // With one frame in flight the next is asked for as soon as this one is decoded, so that its
  // transfer and decoding overlap this one's drawing; with the wide window, once this one is drawn. A hidden
  // page draws nothing, and asks for nothing until it does.
  const askedEarly = flowWindow === 1 && !document.hidden;
  if (lastDrawnSequence !== null && h.sequence > lastDrawnSequence) {
    pushLast(frameSteps, h.sequence - lastDrawnSequence, 30);
  }
  lastDrawnSequence = h.sequence;
  if (askedEarly) acknowledge();
  // Drawn at the next animation frame: latency is measured there.
  requestAnimationFrame(() => {
    const now = performance.now();
    if (drawnTimes.length > 0) pushLast(drawPeriods, now - drawnTimes[drawnTimes.length - 1], 30);
    if (!askedEarly) acknowledge();
    drawnTimes.push(now);
    pushLast(latencies, Date.now() - h.capture_time_ms, 60);
    document.body.dataset.frames = String(Number(document.body.dataset.frames || 0) + 1);
  });
}

function decodeNext() {
  if (decoding || pending === null) return;
  const frame = pending;
  pending = null;
  if (frame.draco.byteLength === 0) {  // nobody in view
    show(frame, new THREE.BufferGeometry());
    return decodeNext();
  }
  decoding = true;
  draco.decodeDracoFile(frame.draco, (geometry) => {
    decoding = false;
    if (paused) acknowledge();
    else show(frame, geometry);
    decodeNext();
  }, null, null, THREE.SRGBColorSpace, (error) => {
    decoding = false;
    acknowledge();
    $('status').textContent = `a frame could not be decoded: ${error}`;
    decodeNext();
  });
}

const token = new URLSearchParams(location.search).get('token');
const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/stream${token ? `?token=${encodeURIComponent(token)}` : ''}`;
let socket;
function connect() {
  socket = new WebSocket(url);
  socket.binaryType = 'arraybuffer';
  socket.onopen = () => {
    $('status').textContent = 'connected';
    flowWindow = WIDE_WINDOW;  // a new connection starts over (flow control above)
    drawPeriods.length = frameSteps.length = 0;
    lastDrawnSequence = null;
    retryAt = 0;
    socket.send(JSON.stringify({ type: 'flow', window: flowWindow }));
    document.body.dataset.flowWindow = String(flowWindow);
    // A new connection starts playing: a paused viewer says so again, or the server sends it
    // every frame (which it would acknowledge unread).
    if (paused) socket.send(JSON.stringify({ type: 'pause' }));
  };
  socket.onclose = (event) => {
    $('status').textContent = `disconnected (${event.code}${event.reason ? `: ${event.reason}` : ''}); retrying…`;
    setTimeout(connect, 1000);
  };
  socket.onmessage = (event) => {
    if (typeof event.data === 'string') {
      const message = JSON.parse(event.data);
      if (message.type === 'hello') {
        cameras = message.cameras;
        const select = $('viewpoint');
        select.length = 1;
        cameras.forEach((c, i) => select.add(new Option(c.name, String(i))));
        $('status').textContent = `${message.capture}: ${cameras.length} cameras, ${message.fps} fps, level of detail ${message.lod}`;
      }
      return;
    }
    received.push([performance.now(), event.data.byteLength]);
    let frame = null;
    try {
      if (!paused) frame = parseFrame(event.data);
    } catch (error) {
      $('status').textContent = `a frame's header could not be read: ${error}`;
    }
    if (frame === null) return acknowledge();
    if (pending !== null) acknowledge();  // the older one is skipped
    pending = frame;
    decodeNext();
  };
}
connect();

$('play').addEventListener('click', () => {
  paused = !paused;
  $('play').textContent = paused ? 'play' : 'pause';
  // The server stops sending to a paused viewer: no bandwidth for frames nobody looks at.
  if (socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify({ type: paused ? 'pause' : 'resume' }));
});

// Drawn on demand: when a frame arrives, the view moves or a setting changes (a loop at the
// display's rate would spend the CPU of a machine without a GPU on unchanged pictures).
let redraw = true;
function requestRedraw() { redraw = true; }
controls.addEventListener('change', requestRedraw);
for (const id of ['color', 'wireframe', 'viewpoint']) $(id).addEventListener('change', requestRedraw);
window.addEventListener('resize', requestRedraw);
renderer.setAnimationLoop(() => {
  if (controls.enabled) controls.update();
  if (!redraw) return;
  redraw = false;
  renderer.render(scene, camera);
});
