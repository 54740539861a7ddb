// view/page/app.js -- the live view's page (view/iso_display.h states the
// wire format): draws the mesh each frame the server sends, coloured by
// distortion, and, when the scene has a `view` device, is a control surface:
// a gizmo on the handle, a handle picker, keyboard nudges and a stop button.
//
// What it commands is a pose target (devices/iso_dev_view.h says why), sent as a
// small binary message with the page's own sequence number and clock. While
// it holds control it sends its target every KEEPALIVE_MS, so that the
// device can tell a quiet page (stale) from a user holding still. Tests read
// the page through window.isoView and the body's data-frames/data-tick.
(function () {
'use strict';
// For tests: when the page got where, on its clock (0: navigation start).
var timing = {script: performance.now()};
function mark(k) { if (!(k in timing)) timing[k] = performance.now(); }
var MAGIC = 0x464f5349, HEADER = 64, POSE = 56, TOPO_MAGIC = 0x544f5349, TOPO_HEADER = 16;
var VERSION = 1, TAKE = 1, RELEASE = 2, TARGET = 3, STOP = 4, UNSTOP = 5;
var FLAG_ESTOP = 1, FLAG_TARGETING = 2, FLAG_STALE = 4, FLAG_HOLDER = 8;
var KEEPALIVE_MS = 25;
var $ = function (id) { return document.getElementById(id); };
var view = $('view');
// A software renderer (SwiftShader, llvmpipe: a machine without a GPU) draws
// without antialiasing, which costs it several times the frame.
function softwareGL() {
  try {
    var gl = document.createElement('canvas').getContext('webgl');
    var info = gl && gl.getExtension('WEBGL_debug_renderer_info');
    return /swiftshader|llvmpipe|software/i.test(info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : '');
  } catch (e) { return false; }
}
var soft = softwareGL();
mark('gl_probed');
var renderer = new THREE.WebGLRenderer({antialias: !soft});
mark('renderer');
renderer.setPixelRatio(window.devicePixelRatio || 1);
renderer.setClearColor(0x181a1f);
view.appendChild(renderer.domElement);
var scene = new THREE.Scene();
var camera = new THREE.PerspectiveCamera(35, 1, 0.01, 1000);
scene.add(new THREE.AmbientLight(0xffffff, 0.35));
var sun = new THREE.DirectionalLight(0xffffff, 0.75);
sun.position.set(0.3, 0.5, 1);
camera.add(sun);
scene.add(camera);
var target = new THREE.Vector3(), orbit = {yaw: 0.5, pitch: 0.35, dist: 10};
var controls = null, dirty = true;
function place() {
  var cp = Math.cos(orbit.pitch);
  camera.up.set(0, 0, 1);
  camera.position.set(target.x + orbit.dist * cp * Math.cos(orbit.yaw),
    target.y + orbit.dist * cp * Math.sin(orbit.yaw), target.z + orbit.dist * Math.sin(orbit.pitch));
  camera.lookAt(target);
  dirty = true;
}
// A tiny orbit control for when libjs-three's examples are absent: drag
// turns (unless the handle is being dragged), wheel zooms.
function ownOrbit() {
  var drag = null, el = renderer.domElement;
  el.addEventListener('mousedown', function (e) {
    if (!e.ctrlKey && !(gizmo && gizmo.dragging)) drag = [e.clientX, e.clientY];
  });
  window.addEventListener('mouseup', function () { drag = null; });
  window.addEventListener('mousemove', function (e) {
    if (!drag) return;
    orbit.yaw -= (e.clientX - drag[0]) * 0.01;
    orbit.pitch = Math.max(-1.5, Math.min(1.5, orbit.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY]; place();
  });
  el.addEventListener('wheel', function (e) {
    e.preventDefault(); orbit.dist *= Math.exp(e.deltaY * 0.001); place();
  }, {passive: false});
}
function resize() {
  var w = view.clientWidth || 800, h = view.clientHeight || 600;
  renderer.setSize(w, h); camera.aspect = w / h; camera.updateProjectionMatrix(); dirty = true;
}
window.addEventListener('resize', resize);

// ---- the mesh -------------------------------------------------------------
var topo = null, geom = null, pos = null, col = null, marks = null, markPos = null;
var frames = 0, full = 0.1, lastX = null;
var stops = [[0.23, 0.49, 0.85], [0.96, 0.84, 0.26], [0.86, 0.16, 0.12]];
function strainColor(s, out) {
  var t = s / full; if (!(t > 0)) t = 0; if (t > 1) t = 1;
  var k = t < 0.5 ? 0 : 1, u = t < 0.5 ? t * 2 : (t - 0.5) * 2;
  for (var c = 0; c < 3; c++) out[c] = stops[k][c] + (stops[k + 1][c] - stops[k][c]) * u;
}
function len(x, i, j) {
  var dx = x[3 * i] - x[3 * j], dy = x[3 * i + 1] - x[3 * j + 1], dz = x[3 * i + 2] - x[3 * j + 2];
  return Math.sqrt(dx * dx + dy * dy + dz * dz);
}
// The binary topology (iso_display.h): its JSON, with the arrays that
// follow it as typed arrays over the message; null if the sizes disagree.
function topologyOf(buf) {
  var dv = new DataView(buf), nv = dv.getUint32(4, true), nt = dv.getUint32(8, true);
  var j = dv.getUint32(12, true), at = TOPO_HEADER + j;
  if (j % 4 || buf.byteLength !== at + 12 * nv + 12 * nt + nv) return null;
  var t = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, TOPO_HEADER, j)));
  if (t.nv !== nv || t.nt !== nt) return null;
  t.rest = new Float32Array(buf, at, 3 * nv);
  t.tri = new Uint32Array(buf, at + 12 * nv, 3 * nt);
  t.kind = new Uint8Array(buf, at + 12 * nv + 12 * nt, nv);
  return t;
}
function onTopology(t) {
  mark('topology_parsed');
  topo = t; full = t.strain_full || 0.1;
  $('full').textContent = Math.round(full * 100) + '%+';
  topo.rest0 = new Float64Array(t.rest);
  topo.l0 = new Float64Array(t.nt * 3);
  for (var f = 0; f < t.nt; f++) for (var k = 0; k < 3; k++)
    topo.l0[3 * f + k] = len(topo.rest0, t.tri[3 * f + k], t.tri[3 * f + (k + 1) % 3]);
  if (geom) scene.remove(geom.userData.obj);
  geom = new THREE.BufferGeometry();
  pos = new Float32Array(t.nt * 9); col = new Float32Array(t.nt * 9);
  geom.setAttribute('position', new THREE.BufferAttribute(pos, 3));
  geom.setAttribute('color', new THREE.BufferAttribute(col, 3));
  var mat = new THREE.MeshLambertMaterial({vertexColors: THREE.VertexColors, side: THREE.DoubleSide});
  var obj = new THREE.Mesh(geom, mat); geom.userData.obj = obj; scene.add(obj);
  var mk = [];
  for (var i = 0; i < t.nv; i++) if (t.kind[i] !== 1) mk.push(i);
  topo.marked = mk;
  if (marks) scene.remove(marks);
  var mg = new THREE.BufferGeometry();
  markPos = new Float32Array(mk.length * 3);
  var mc = new Float32Array(mk.length * 3);
  for (var m = 0; m < mk.length; m++)
    mc.set(t.kind[mk[m]] === 2 ? [0.9, 0.25, 0.9] : [0.54, 0.56, 0.6], 3 * m);
  mg.setAttribute('position', new THREE.BufferAttribute(markPos, 3));
  mg.setAttribute('color', new THREE.BufferAttribute(mc, 3));
  marks = new THREE.Points(mg, new THREE.PointsMaterial({size: 3, sizeAttenuation: false,
    vertexColors: THREE.VertexColors}));
  scene.add(marks);
  var lo = [1e300, 1e300, 1e300], hi = [-1e300, -1e300, -1e300];
  for (var v = 0; v < t.nv; v++) for (var c = 0; c < 3; c++) {
    lo[c] = Math.min(lo[c], t.rest[3 * v + c]); hi[c] = Math.max(hi[c], t.rest[3 * v + c]);
  }
  target.set((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2);
  topo.diag = Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) || 1;
  var r = 0.5 * topo.diag;
  // The bounding sphere fills about three quarters of the view's height:
  // room for the gizmo, whose arrows keep their size on screen (about a
  // sixth of the height), on a handle at the mesh's edge (at 1.05 the
  // cactus's up arrow started above the view).
  orbit.dist = r / Math.sin(camera.fov * Math.PI / 360) * 1.35;
  camera.near = r / 100; camera.far = r * 100; camera.updateProjectionMatrix();
  place();
  if (THREE.OrbitControls && !controls) {
    controls = new THREE.OrbitControls(camera, renderer.domElement);
    controls.addEventListener('change', function () { dirty = true; });
  } else if (!controls) { controls = 'own'; ownOrbit(); }
  if (controls !== 'own') { controls.target.copy(target); controls.update(); }
  surface.setup(t.control);
  // the rest pose until a frame comes: drawn at the next animation frame
  // unless a frame is there by then (it usually is: it follows the topology)
  latest = {x: topo.rest0, frame: false}; lastX = null;
  mark('topology_done');
}
function samePositions(a, b) {
  if (!b || a.length !== b.length) return false;
  for (var i = 0; i < a.length; i++) if (a[i] !== b[i]) return false;
  return true;
}
var rgb = [0, 0, 0], HANDLE_RGB = [0.9, 0.25, 0.9], FIXED_RGB = [0.45, 0.47, 0.52];
function update(x) {
  var t = topo, tri = t.tri, kind = t.kind;
  lastX = x;
  for (var f = 0; f < t.nt; f++) {
    var s = 0, h = false, fx = false;
    for (var k = 0; k < 3; k++) {
      var i = tri[3 * f + k], j = tri[3 * f + (k + 1) % 3], l0 = t.l0[3 * f + k];
      var d = l0 > 0 ? Math.abs(len(x, i, j) - l0) / l0 : 0; if (d > s) s = d;
      pos[9 * f + 3 * k] = x[3 * i]; pos[9 * f + 3 * k + 1] = x[3 * i + 1];
      pos[9 * f + 3 * k + 2] = x[3 * i + 2];
      h = h || kind[i] === 2; fx = fx || kind[i] === 0;
    }
    strainColor(s, rgb);
    if (h) for (var c = 0; c < 3; c++) rgb[c] = rgb[c] * 0.5 + HANDLE_RGB[c] * 0.5;
    else if (fx) for (var c2 = 0; c2 < 3; c2++) rgb[c2] = rgb[c2] * 0.45 + FIXED_RGB[c2] * 0.55;
    for (var q = 0; q < 3; q++) col.set(rgb, 9 * f + 3 * q);
  }
  for (var m = 0; m < t.marked.length; m++) {
    var v = t.marked[m];
    markPos[3 * m] = x[3 * v]; markPos[3 * m + 1] = x[3 * v + 1]; markPos[3 * m + 2] = x[3 * v + 2];
  }
  geom.attributes.position.needsUpdate = true; geom.attributes.color.needsUpdate = true;
  geom.computeVertexNormals(); geom.computeBoundingSphere();
  marks.geometry.attributes.position.needsUpdate = true;
  marks.geometry.computeBoundingSphere();
  dirty = true;
}

// ---- drawing: on the browser's frames, when something changed -------------
var spin = false, rafs = 0, drawn = 0, latest = null, shown = 0, lastTick = 0;
// The mesh as shown (positions and the flat strain colours as vertex
// colours), as a binary glTF file, with three.js's GLTFExporter from
// libjs-three's examples. The page's address with ?glb=1 saves once after
// the first frame drawn and sets data-glb to the file's size (a headless
// browser has no button to press).
function saveGlb() {
  if (!THREE.GLTFExporter || !geom) { $('glb').textContent = 'no GLTFExporter (libjs-three)'; return; }
  new THREE.GLTFExporter().parse(geom.userData.obj, function (glb) {
    document.body.setAttribute('data-glb', String(glb.byteLength));
    var a = document.createElement('a');
    a.href = URL.createObjectURL(new Blob([glb], {type: 'model/gltf-binary'}));
    a.download = 'isoshape_tick_' + lastTick + '.glb';
    document.body.appendChild(a); a.click(); document.body.removeChild(a);
  }, {binary: true});
}
$('glb').onclick = saveGlb;
function tick() {
  rafs++;
  if (spin) { orbit.yaw += 0.01; if (controls && controls !== 'own') { place(); controls.update(); } else place(); }
  // the newest frame only: frames that came faster than the page draws are
  // skipped, so a slow page never falls behind the stream (and the server
  // never finds it too slow to read)
  var fresh = latest && latest.frame;
  if (latest && topo) {
    if (!samePositions(latest.x, lastX)) update(latest.x); // the loop publishes a mesh at rest too
    latest = null;
  }
  if (statsText !== statsShown && performance.now() - statsAt >= STATS_MS) {
    $('stats').textContent = statsShown = statsText; statsAt = performance.now();
  }
  if (dirty) {
    renderer.render(scene, camera); drawn++; dirty = false;
    if (topo) mark('mesh_rendered'); // the first: its shaders compiled
    if (undrawn.length) { var at = performance.now(); undrawn.forEach(function (e) { e[4] = at; }); undrawn = []; }
  }
  if (fresh && topo) { // a frame from the loop is on the screen
    shown++; mark('first_frame_drawn');
    if (shown === 1 && /[?&]glb=1/.test(location.search)) saveGlb();
  }
  window.requestAnimationFrame(tick);
}

// ---- frames from the server -------------------------------------------------
function fmt(v) { return v.toFixed(2); }
// The stats line is text: rewritten at most every STATS_MS, not per frame.
var STATS_MS = 250, statsText = '', statsShown = '', statsAt = -1e9;
// For tests: each target change the ticks applied, sent -> its frame's
// arrival (lat), and as [seq, sent, arrived, the frame's tick, drawn] with
// the page's clock (latLog; drawn: when a render with that frame or a later
// one returned). The last LOG_MAX only: a page may drive for hours.
var LOG_MAX = 4096, lat = [], latLog = [], undrawn = [];
function logPush(a, v) { a.push(v); if (a.length > LOG_MAX) a.shift(); }
// Returns the frame's tick number (null: not a frame), for the "took".
function onFrame(buf) {
  var arrived = performance.now(), dv = new DataView(buf);
  mark('first_frame');
  if (buf.byteLength < HEADER || dv.getUint32(0, true) !== MAGIC) return null;
  var tick = dv.getFloat64(8, true), poses = [];
  var nv = dv.getUint32(4, true), nh = dv.getUint32(36, true);
  if (!topo || nv !== topo.nv || buf.byteLength !== HEADER + POSE * nh + 12 * nv) return tick;
  for (var h = 0; h < nh; h++) {
    var o = HEADER + POSE * h, p = [];
    for (var k = 0; k < 7; k++) p.push(dv.getFloat64(o + 8 * k, true));
    poses.push(p);
  }
  latest = {x: new Float32Array(buf, HEADER + POSE * nh, 3 * nv), frame: true};
  frames++;
  surface.frame({tick: tick, poses: poses, conn: dv.getUint32(40, true), seq: dv.getUint32(44, true),
    pageMs: dv.getFloat64(48, true), flags: dv.getUint32(56, true), arrived: arrived});
  statsText = 'tick ' + tick + ' | tick ms median ' + fmt(dv.getFloat32(16, true)) +
    ' p99 ' + fmt(dv.getFloat32(20, true)) + ' max ' + fmt(dv.getFloat32(24, true)) +
    ' | missed ' + dv.getUint32(32, true) + ' | latency ' + fmt(dv.getFloat32(28, true)) + ' ms' +
    // what this page measures: its last 64 commands, sent to the frame that applied them
    (lat.length ? ' | your input to frame ' + fmt(quantile(lat.slice(-64), 0.5)) + ' ms' : '');
  document.body.setAttribute('data-frames', String(frames));
  document.body.setAttribute('data-tick', String(tick));
  lastTick = tick;
  return tick;
}

// ---- the control surface -----------------------------------------------------
var gizmo = null; // THREE.TransformControls, when libjs-three has it
var surface = (function () {
  var info = null, me = 0, may = false, holder = 0, stopped = false, ended = false;
  var picked = 0, seq = 0, ws = null, keepalive = null, flags = 0;
  var moveStep = 0.01, turnStep = 5 * Math.PI / 180; // moveStep: of the diagonal
  var handleObj = new THREE.Object3D(); // where the page wants the handle (the target)
  var actual = [];                      // each mesh handle's pose, [p, quaternion]
  var synced = false;                   // the target starts from the handle's pose
  var pending = [];                     // [seq, sent at] of target changes, for latency
  var echo = [0, 0];                    // the last command the ticks applied: [conn, seq]
  var sentSeq = 0;                      // the last target's sequence number
  var changedSeq = 0;                   // the last target change's (a keepalive is none)
  var armUnstop = 0;
  scene.add(handleObj);
  function centre(j) { return new THREE.Vector3().fromArray(info.handles[j].centre); }
  function meshHandle(j) { return info.handles[j].handle; }
  // Where the picked handle is now: the frame's pose applied to its centre.
  function actualPose(j) {
    var a = actual[meshHandle(j)];
    if (!a) return {pos: centre(j), quat: new THREE.Quaternion()};
    var q = new THREE.Quaternion(a[3], a[4], a[5], a[6]);
    return {pos: centre(j).applyQuaternion(q).add(new THREE.Vector3(a[0], a[1], a[2])), quat: q};
  }
  function syncTarget() {
    var a = actualPose(picked);
    if (!synced || !handleObj.position.equals(a.pos) || !handleObj.quaternion.equals(a.quat)) {
      handleObj.position.copy(a.pos); handleObj.quaternion.copy(a.quat);
      handleObj.updateMatrixWorld(); dirty = true;
    }
    synced = true;
  }
  function send(type, fill, len) {
    if (!ws || ws.readyState !== 1) return 0;
    var b = new ArrayBuffer(len || 16), dv = new DataView(b);
    seq++;
    dv.setUint8(0, VERSION); dv.setUint8(1, type);
    dv.setUint32(4, seq, true); dv.setFloat64(8, performance.now(), true);
    if (fill) fill(dv);
    ws.send(b);
    return seq;
  }
  // The target as the device wants it: the pose rest -> target, p = q - Q c
  // and Q's rotation vector (doubles all the way: JS numbers are).
  function targetPose() {
    var Q = handleObj.quaternion.clone();
    if (Q.w < 0) { Q.x = -Q.x; Q.y = -Q.y; Q.z = -Q.z; Q.w = -Q.w; }
    var s = Math.sqrt(Q.x * Q.x + Q.y * Q.y + Q.z * Q.z), ang = 2 * Math.atan2(s, Q.w);
    var k = s > 1e-300 ? ang / s : 2;
    var c = centre(picked).applyQuaternion(handleObj.quaternion);
    return [handleObj.position.x - c.x, handleObj.position.y - c.y, handleObj.position.z - c.z,
      Q.x * k, Q.y * k, Q.z * k];
  }
  function sendTarget(changed) {
    if (holder !== me || !me || stopped || ended || !synced) return;
    var p = targetPose();
    var s = send(TARGET, function (dv) {
      dv.setUint8(2, picked);
      for (var i = 0; i < 6; i++) dv.setFloat64(16 + 8 * i, p[i], true);
    }, 64);
    if (s && changed) { pending.push([s, performance.now()]); changedSeq = s; }
    if (s) { lastSent = p; sentSeq = s; }
  }
  var lastSent = null;
  function mine() { return holder === me && me !== 0; }
  // The panel as the state says; a frame that changes none of it writes
  // nothing (a DOM write costs the browser a layout and a paint, each frame).
  var shownKey = null;
  function show() {
    var key = [holder, me, may, stopped, ended, flags & (FLAG_STALE | FLAG_TARGETING), !!gizmo].join();
    if (key === shownKey) return;
    shownKey = key;
    $('who').textContent = holder === 0 ? 'nobody' : holder === me ? 'you (viewer ' + me + ')' :
      'viewer ' + holder;
    var st = stopped ? 'STOPPED' : ended ? 'run ended' : holder === 0 ? 'released' :
      (flags & FLAG_STALE) ? 'stale' : (flags & FLAG_TARGETING) ? 'live' : 'waiting';
    $('state').textContent = st;
    $('take').disabled = !may || holder !== 0 || ended;
    $('release').disabled = !mine();
    $('stop').disabled = !may || ended;
    $('stop').className = stopped ? 'on' : '';
    $('stop').textContent = stopped ? 'STOPPED' : 'STOP (Esc)';
    $('unstop').style.display = stopped && may && !ended ? 'block' : 'none';
    if (gizmo) { gizmo.enabled = mine() && !stopped && !ended; gizmo.visible = gizmo.enabled; }
    dirty = true;
  }
  function setup(ctl) {
    info = ctl;
    if (!ctl) { $('readonly').textContent = 'watching only: this scene has no view device'; return; }
    $('readonly').style.display = 'none'; $('surface').style.display = 'block';
    var sel = $('handle');
    sel.innerHTML = '';
    ctl.handles.forEach(function (h, j) {
      var o = document.createElement('option'); o.value = j; o.textContent = h.name; sel.appendChild(o);
    });
    sel.onchange = function () { picked = +sel.value; syncTarget(); };
    if (THREE.TransformControls && !gizmo) {
      gizmo = new THREE.TransformControls(camera, renderer.domElement);
      gizmo.setSize(1.2);
      gizmo.attach(handleObj);
      gizmo.addEventListener('change', function () { dirty = true; });
      gizmo.addEventListener('objectChange', function () { sendTarget(true); });
      gizmo.addEventListener('dragging-changed', function (e) {
        if (controls && controls !== 'own') controls.enabled = !e.value;
      });
      scene.add(gizmo);
    } else if (!gizmo) ownGizmo();
    $('take').onclick = function () { send(TAKE); };
    $('release').onclick = function () { send(RELEASE); };
    // a hidden tab's timers are throttled to a second or a minute: it lets
    // go rather than hold control with a stale hand (the server ends a
    // holder's control after 3 s without a command anyway)
    document.onvisibilitychange = function () { if (document.hidden && mine()) send(RELEASE); };
    $('mode').onclick = function () { setMode(mode === 'translate' ? 'rotate' : 'translate'); };
    // an e-stop acts when it is pressed, not when the button is let go; a
    // handler, not a listener added: setup runs again on each reconnect
    $('stop').onmousedown = function (e) { if (e.button === 0) send(STOP); };
    $('unstop').onclick = function () { // a deliberate second click within 3 s
      var now = performance.now();
      if (now - armUnstop < 3000) { send(UNSTOP); armUnstop = 0; $('unstop').textContent = 'Release the stop...'; }
      else { armUnstop = now; $('unstop').textContent = 'Click again to release the stop'; }
    };
    steps(); show();
  }
  var mode = 'translate';
  function setMode(m) {
    mode = m; if (gizmo) gizmo.setMode(m);
    $('mode').textContent = m === 'translate' ? 'turn (R)' : 'move (G)';
  }
  // Without TransformControls: Ctrl+drag moves the target in the view's plane.
  function ownGizmo() {
    var el = renderer.domElement, from = null;
    el.addEventListener('mousedown', function (e) {
      if (e.ctrlKey && mine() && !stopped) from = [e.clientX, e.clientY];
    });
    window.addEventListener('mouseup', function () { from = null; });
    window.addEventListener('mousemove', function (e) {
      if (!from) return;
      var k = orbit.dist * Math.tan(camera.fov * Math.PI / 360) * 2 / (view.clientHeight || 600);
      var right = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 0);
      var up = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 1);
      handleObj.position.addScaledVector(right, (e.clientX - from[0]) * k)
        .addScaledVector(up, -(e.clientY - from[1]) * k);
      from = [e.clientX, e.clientY]; sendTarget(true); dirty = true;
    });
  }
  function steps() {
    $('steps').textContent = (moveStep * 100).toPrecision(2) + '% of the diagonal, ' +
      (turnStep * 180 / Math.PI).toPrecision(2) + ' deg';
  }
  function nudge(axis, sign, turn) {
    if (!mine() || stopped || !synced) return;
    var v = new THREE.Vector3(); v.setComponent(axis, sign);
    if (turn) handleObj.quaternion.premultiply(new THREE.Quaternion().setFromAxisAngle(v, turnStep));
    else handleObj.position.addScaledVector(v, moveStep * topo.diag);
    handleObj.updateMatrixWorld(); sendTarget(true); dirty = true;
  }
  function key(e) {
    if (!info) return;
    var k = e.key, lower = k.length === 1 ? k.toLowerCase() : k, sign = e.shiftKey ? -1 : 1;
    if (k === 'Escape') { send(STOP); e.preventDefault(); return; } // wherever the focus is
    if (e.target.tagName === 'SELECT' || e.target.tagName === 'INPUT') return;
    if (e.ctrlKey || e.metaKey || e.altKey) return; // the browser's own shortcuts
    if (k === 'Enter') send(TAKE);
    else if (lower === 'q') send(RELEASE);
    else if (lower === 'g') setMode('translate');
    else if (lower === 'r') setMode('rotate');
    else if ('xyz'.indexOf(lower) >= 0 && lower.length === 1) nudge('xyz'.indexOf(lower), sign, false);
    else if ('abc'.indexOf(lower) >= 0 && lower.length === 1) nudge('abc'.indexOf(lower), sign, true);
    else if (k === '[') { moveStep /= 2; turnStep /= 2; steps(); }
    else if (k === ']') { moveStep *= 2; turnStep *= 2; steps(); }
    else if (k === 'Tab') {
      picked = (picked + 1) % info.handles.length; $('handle').value = picked; syncTarget();
    } else return;
    e.preventDefault();
  }
  window.addEventListener('keydown', key);
  function control(m) {
    var wasMine = mine();
    me = m.you; may = m.may_command; holder = m.holder; ended = m.ended;
    if (m.stop !== stopped) { stopped = m.stop; synced = false; } // the stop drops every target
    $('why').textContent = m.why || '';
    if (mine() && !wasMine) syncTarget(); // control starts from where the handle is
    if (mine() && !keepalive) keepalive = setInterval(function () { sendTarget(false); }, KEEPALIVE_MS);
    if (!mine() && keepalive) { clearInterval(keepalive); keepalive = null; }
    show();
  }
  function frame(f) {
    actual = f.poses; flags = f.flags; echo = [f.conn, f.seq];
    if (f.conn === me && me) // each target change the tick applied: sent -> frame arrived
      while (pending.length && pending[0][0] <= f.seq) {
        var e = [pending[0][0], pending[0][1], f.arrived, f.tick, null];
        logPush(lat, f.arrived - pending[0][1]); logPush(latLog, e); undrawn.push(e); pending.shift();
      }
    if (info && (!mine() || stopped || !synced)) syncTarget(); // the gizmo shows the handle
    show();
  }
  // How far the handle is from the target: the largest difference of the
  // poses' positions and quaternions (the frame's pose is the loop's, in
  // doubles), or null before there is both.
  function gap() {
    var a = info && synced ? actual[meshHandle(picked)] : null;
    if (!a) return null;
    var t = targetPose(), Q = handleObj.quaternion, sg = a[3] * Q.x + a[4] * Q.y + a[5] * Q.z + a[6] * Q.w < 0 ? -1 : 1;
    var d = Math.max(Math.abs(a[0] - t[0]), Math.abs(a[1] - t[1]), Math.abs(a[2] - t[2]));
    return Math.max(d, Math.abs(a[3] - sg * Q.x), Math.abs(a[4] - sg * Q.y), Math.abs(a[5] - sg * Q.z),
      Math.abs(a[6] - sg * Q.w));
  }
  function connected(sock) { ws = sock; seq = 0; pending = []; }
  function closed() { ws = null; holder = 0; me = 0; if (keepalive) { clearInterval(keepalive); keepalive = null; } if (info) show(); }
  return {setup: setup, control: control, frame: frame, connected: connected, closed: closed,
    handleObj: handleObj,
    state: function () {
      return {you: me, may_command: may, holder: holder, stop: stopped, ended: ended,
        picked: picked, mode: mode, synced: synced, seq: seq, flags: flags,
        target: info && synced ? targetPose() : null, sent: lastSent, sent_seq: sentSeq,
        changed_seq: changedSeq,
        echo: echo, actual: info ? actual[meshHandle(picked)] || null : null, gap: gap(),
        centre: info ? info.handles[picked].centre : null, diag: topo ? topo.diag : null,
        gizmo: handleObj.position.toArray(), quat: handleObj.quaternion.toArray()};
    }};
})();

function onNote(n) { var el = $('note'); el.textContent = n.text; el.style.display = 'block'; }

function connect() {
  var tok = new URLSearchParams(location.search).get('token');
  var ws = new WebSocket((location.protocol === 'https:' ? 'wss://' : 'ws://') + location.host + '/ws' +
    (tok ? '?token=' + encodeURIComponent(tok) : ''));
  ws.binaryType = 'arraybuffer';
  ws.onopen = function () { mark('ws_open'); $('conn').textContent = 'live'; surface.connected(ws); };
  ws.onclose = function () {
    $('conn').textContent = 'disconnected, retrying'; surface.closed(); setTimeout(connect, 1000);
  };
  ws.onmessage = function (e) {
    // Each frame taken is said at once: the server sends the next only then
    // (iso_display.h), so frames never queue up for a page busy drawing.
    if (typeof e.data !== 'string') {
      if (e.data.byteLength >= TOPO_HEADER && new DataView(e.data).getUint32(0, true) === TOPO_MAGIC) {
        if (!topo) mark('topology');
        var tp = topologyOf(e.data);
        if (tp) onTopology(tp); else $('conn').textContent = 'a topology this page cannot read';
        return;
      }
      var t = onFrame(e.data);
      if (t !== null && ws.readyState === 1) ws.send('{"type":"took","tick":' + t + '}');
      return;
    }
    var m = JSON.parse(e.data);
    if (m.type === 'control') surface.control(m);
    else if (m.type === 'note') onNote(m);
  };
}

// ---- for tests: the page's state, and where things are on the screen ---------
function quantile(a, q) {
  if (!a.length) return null;
  var s = a.slice().sort(function (x, y) { return x - y; });
  return s[Math.min(s.length - 1, Math.max(0, Math.ceil(q * s.length) - 1))];
}
function screenOf(v) {
  var p = v.clone().project(camera), r = renderer.domElement.getBoundingClientRect();
  return [r.left + (p.x + 1) / 2 * r.width, r.top + (1 - p.y) / 2 * r.height];
}
window.isoView = {
  state: function () {
    var s = surface.state();
    s.frames = frames; s.rafs = rafs; s.drawn = drawn; s.frames_drawn = shown; s.now = performance.now();
    s.latency = {n: lat.length, median: quantile(lat, 0.5), p99: quantile(lat, 0.99)};
    s.gizmo_ok = !!gizmo;
    s.axis = gizmo ? gizmo.axis : null; s.dragging = gizmo ? !!gizmo.dragging : false;
    return s;
  },
  // The screen point of the gizmo's picker for `axis` ('X', 'Y' or 'Z') in
  // its current mode, and of the gizmo's centre.
  pickerAt: function (axis) {
    if (!gizmo) return null;
    gizmo.updateMatrixWorld();
    var g = gizmo.children[0], mode = gizmo.getMode ? gizmo.getMode() : gizmo.mode, hit = null;
    g.picker[mode].children.forEach(function (o) { if (o.name === axis) hit = o; });
    if (!hit) return null;
    // the pickers' geometry has their offsets baked in: its box's middle
    hit.geometry.computeBoundingBox();
    var mid = hit.geometry.boundingBox.getCenter(new THREE.Vector3()).applyMatrix4(hit.matrixWorld);
    var c = surface.handleObj.getWorldPosition(new THREE.Vector3());
    return {at: screenOf(mid), centre: screenOf(c), world: mid.distanceTo(c)};
  },
  screenOf: function (x, y, z) { return screenOf(new THREE.Vector3(x, y, z)); },
  // Where on the world axis ('X', 'Y' or 'Z') through the target the ray of
  // viewport point (x, y) passes closest: that axis's coordinate. A drag of
  // the gizmo's arrow from one point to another moves the target by the
  // difference (perspective included), so tests can say what it should.
  axisAt: function (axis, x, y) {
    var r = renderer.domElement.getBoundingClientRect(), ray = new THREE.Raycaster();
    ray.setFromCamera(new THREE.Vector2((x - r.left) / r.width * 2 - 1, 1 - (y - r.top) / r.height * 2), camera);
    var k = 'XYZ'.indexOf(axis), u = new THREE.Vector3(), o = surface.handleObj.getWorldPosition(new THREE.Vector3());
    u.setComponent(k, 1);
    var p = ray.ray.origin, d = ray.ray.direction, w = o.clone().sub(p);
    var b = u.dot(d), c = d.dot(d), e = d.dot(w), t = (b * e - c * u.dot(w)) / (c - b * b);
    return o.getComponent(k) + t;
  },
  spin: function (on) { spin = !!on; },
  latencies: function () { return lat.slice(); },
  latencyLog: function () { return latLog.slice(); },
  // The marks, and the navigation's and the scripts' own timing entries.
  marks: function () {
    var m = {}, nav = performance.getEntriesByType('navigation')[0];
    for (var k in timing) m[k] = timing[k];
    if (nav) { m.html_end = nav.responseEnd; m.dom_loaded = nav.domContentLoadedEventStart; }
    performance.getEntriesByType('resource').forEach(function (r) {
      var n = r.name.replace(/^.*\//, '').replace(/\.js.*$/, '');
      m[n + '_start'] = r.startTime; m[n + '_end'] = r.responseEnd;
    });
    return m;
  },
  clearLatencies: function () { lat.length = 0; latLog.length = 0; undrawn = []; }
};

resize();
connect();
window.requestAnimationFrame(tick);
})();
