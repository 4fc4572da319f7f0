// AgentWorld teleop page: keyboard -> controls over a WebSocket; camera frames (JPEG) <- server.
// Served by stages/teleop/server.py with the access token in every URL; no external resources.
"use strict";
(() => {
  const token = new URLSearchParams(location.search).get("token") || "";
  const $ = (id) => document.getElementById(id);
  const held = new Set();
  const state = { mode: 0, gripper: 0, seq: 0, frames: 0, fps: 0, status: null, connected: false, xr: null };
  window.teleopState = state; // read-only introspection (tests, the console)

  const wsUrl = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws?token=${encodeURIComponent(token)}`;
  let ws = null;

  function send(obj) {
    if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(obj));
  }

  function axis(plus, minus) {
    return (held.has(plus) ? 1 : 0) - (held.has(minus) ? 1 : 0);
  }

  function command() {
    let base = [0, 0, 0];
    let jog = [0, 0, 0, 0, 0, 0];
    if (state.mode === 0) {
      base = [axis("KeyW", "KeyS"), axis("KeyA", "KeyD"), axis("KeyQ", "KeyE")];
    } else {
      jog = [axis("KeyW", "KeyS"), axis("KeyA", "KeyD"), axis("KeyR", "KeyF"),
             axis("KeyJ", "KeyL"), axis("KeyI", "KeyK"), axis("KeyQ", "KeyE")];
    }
    state.seq += 1;
    return { type: "cmd", seq: state.seq, base, jog, mode: state.mode, gripper: state.gripper };
  }

  function sendCommand() { send(command()); }

  function setMode(m) {
    state.mode = m;
    $("btn-mode").textContent = `Mode: ${m === 0 ? "locomotion" : "manipulation"} (M)`;
    sendCommand();
  }

  function toggleGripper() {
    state.gripper = state.gripper ? 0 : 1;
    $("btn-gripper").textContent = `Gripper: ${state.gripper ? "closed" : "open"} (G / Space)`;
    sendCommand();
  }

  const CONTROL_KEYS = new Set(["KeyW", "KeyA", "KeyS", "KeyD", "KeyQ", "KeyE", "KeyR", "KeyF",
                                "KeyI", "KeyJ", "KeyK", "KeyL"]);
  document.addEventListener("keydown", (e) => {
    if (e.target && e.target.tagName === "INPUT") return;
    if (e.code === "KeyM" && !e.repeat) { setMode(state.mode ? 0 : 1); e.preventDefault(); return; }
    if ((e.code === "KeyG" || e.code === "Space") && !e.repeat) { toggleGripper(); e.preventDefault(); return; }
    if (CONTROL_KEYS.has(e.code)) {
      e.preventDefault();
      if (!held.has(e.code)) { held.add(e.code); sendCommand(); }
    }
  });
  document.addEventListener("keyup", (e) => {
    if (held.delete(e.code)) sendCommand();
  });
  window.addEventListener("blur", () => { held.clear(); sendCommand(); });

  $("btn-mode").addEventListener("click", () => setMode(state.mode ? 0 : 1));
  $("btn-gripper").addEventListener("click", toggleGripper);
  $("btn-start").addEventListener("click", () =>
    send({ type: "episode", action: "start", task: $("instruction").value.trim().slice(0, 200) }));
  $("btn-save").addEventListener("click", () => send({ type: "episode", action: "save" }));
  $("btn-discard").addEventListener("click", () => send({ type: "episode", action: "discard" }));

  // -- frames: b"AWF1", u32 frame id, u8 count, then (u8 name length, name, u32 JPEG length, JPEG)*
  const urls = {};
  const shown = [];
  async function onFrame(buf) {
    const dv = new DataView(buf);
    const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
    if (magic !== "AWF1") return;
    const frame = dv.getUint32(4, true);
    const count = dv.getUint8(8);
    let off = 9;
    const draws = [];
    for (let i = 0; i < count; i++) {
      const n = dv.getUint8(off); off += 1;
      const name = new TextDecoder().decode(new Uint8Array(buf, off, n)); off += n;
      const len = dv.getUint32(off, true); off += 4;
      const img = $(`cam-${name}`);
      if (img) {
        const url = URL.createObjectURL(new Blob([new Uint8Array(buf, off, len)], { type: "image/jpeg" }));
        const old = urls[name];
        urls[name] = url;
        img.src = url;
        draws.push(img.decode().catch(() => {}).finally(() => { if (old) URL.revokeObjectURL(old); }));
      }
      off += len;
    }
    await Promise.all(draws);
    send({ type: "ack", frame });
    state.frames += 1;
    const now = performance.now();
    shown.push(now);
    while (shown.length && now - shown[0] > 2000) shown.shift();
    state.fps = shown.length / 2; // frames shown in the last 2 s, per second
  }

  function onStatus(st) {
    state.status = st;
    $("task").textContent = `${st.task}: ${st.instruction || ""}`;
    $("st-fps").textContent = `display ${state.fps.toFixed(1)} fps`;
    $("st-sim").textContent = `sim ${st.fps} fps`;
    const lat = (v) => (v === null || v === undefined ? "-" : `${v} ms`);
    $("st-lat").textContent = `input ${lat(st.input_ms)} · render->display ${lat(st.display_ms)}`;
    $("st-rec").textContent = st.recording ? `REC episode ${st.episode} (${st.tick} ticks)` : "not recording";
    $("st-rec").className = st.recording ? "on" : "";
    $("st-ep").textContent = `saved ${st.saved}`;
    $("st-msg").textContent = st.last_rejection ? `rejected: ${st.last_rejection}` : "";
  }

  function connect() {
    ws = new WebSocket(wsUrl);
    ws.binaryType = "arraybuffer";
    ws.onopen = () => { state.connected = true; $("st-conn").textContent = "connected"; sendCommand(); };
    ws.onclose = () => {
      state.connected = false;
      $("st-conn").textContent = "disconnected (reload to reconnect)";
    };
    ws.onmessage = (ev) => {
      if (typeof ev.data === "string") {
        try { onStatus(JSON.parse(ev.data)); } catch (err) { /* ignore a bad status */ }
      } else {
        onFrame(ev.data);
      }
    };
  }

  // -- WebXR: head and hand joint poses (XRHand, 25 joints) -> server, ~30 Hz; the robot's head
  // camera drawn in the headset. ?emulate=1 loads IWER (vendored from npm) to emulate a headset.
  const emulate = new URLSearchParams(location.search).get("emulate");
  const round = (m) => Array.from(m, (v) => Math.round(v * 1e5) / 1e5);

  function loadEmulator() {
    return new Promise((resolve, reject) => {
      const s = document.createElement("script");
      s.src = `static/vendor/iwer.min.js?token=${encodeURIComponent(token)}`;
      s.onload = () => {
        const device = new window.IWER.XRDevice(window.IWER.metaQuest3);
        device.installRuntime({ forceInstall: true }); // over the browser's own (headset-less) WebXR
        device.primaryInputMode = "hand";
        window.teleopXrDevice = device;
        resolve();
      };
      s.onerror = () => reject(new Error("the headset emulator (IWER) is not vendored"));
      document.head.appendChild(s);
    });
  }

  function headQuad(gl) {
    const sh = (type, src) => { const o = gl.createShader(type); gl.shaderSource(o, src); gl.compileShader(o); return o; };
    const prog = gl.createProgram();
    gl.attachShader(prog, sh(gl.VERTEX_SHADER,
      "attribute vec2 p; varying vec2 uv; void main() { uv = vec2(p.x * 0.5 + 0.5, 0.5 - p.y * 0.5); gl_Position = vec4(p * 0.8, 0.0, 1.0); }"));
    gl.attachShader(prog, sh(gl.FRAGMENT_SHADER,
      "precision mediump float; varying vec2 uv; uniform sampler2D tex; void main() { gl_FragColor = texture2D(tex, uv); }"));
    gl.linkProgram(prog);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1]), gl.STATIC_DRAW);
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    for (const [k, v] of [[gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE],
                          [gl.TEXTURE_MIN_FILTER, gl.LINEAR], [gl.TEXTURE_MAG_FILTER, gl.LINEAR]]) {
      gl.texParameteri(gl.TEXTURE_2D, k, v);
    }
    return { prog, buf, tex, loc: gl.getAttribLocation(prog, "p"), uploaded: -1 };
  }

  function drawHead(gl, layer, pose, q) {
    gl.bindFramebuffer(gl.FRAMEBUFFER, layer.framebuffer);
    gl.clearColor(0.1, 0.1, 0.1, 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    const img = $("cam-head");
    gl.useProgram(q.prog);
    gl.bindTexture(gl.TEXTURE_2D, q.tex);
    if (img.complete && img.naturalWidth && q.uploaded !== state.frames) {
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, img);
      q.uploaded = state.frames;
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, q.buf);
    gl.enableVertexAttribArray(q.loc);
    gl.vertexAttribPointer(q.loc, 2, gl.FLOAT, false, 0, 0);
    for (const view of pose.views) {
      const vp = layer.getViewport(view);
      gl.viewport(vp.x, vp.y, vp.width, vp.height);
      gl.drawArrays(gl.TRIANGLES, 0, 6);
    }
  }

  async function startXr() {
    const session = await navigator.xr.requestSession("immersive-vr",
      { requiredFeatures: ["local-floor"], optionalFeatures: ["hand-tracking"] });
    const canvas = document.createElement("canvas");
    const gl = canvas.getContext("webgl", { xrCompatible: true });
    if (gl.makeXRCompatible) await gl.makeXRCompatible();
    const layer = new XRWebGLLayer(session, gl);
    session.updateRenderState({ baseLayer: layer });
    const ref = await session.requestReferenceSpace("local-floor");
    const quad = headQuad(gl);
    state.xr = true;
    state.xrSent = 0;
    session.addEventListener("end", () => { state.xr = false; sendCommand(); });
    let last = -1e9;
    const onFrame = (t, frame) => {
      session.requestAnimationFrame(onFrame);
      const pose = frame.getViewerPose(ref);
      if (!pose) return;
      if (t - last >= 33) {
        const hands = {};
        for (const src of session.inputSources) {
          if (!src.hand || (src.handedness !== "left" && src.handedness !== "right")) continue;
          const joints = [];
          for (const space of src.hand.values()) {
            const jp = frame.getJointPose(space, ref);
            if (!jp) break;
            joints.push(round(jp.transform.matrix));
          }
          if (joints.length === 25) hands[src.handedness] = joints;
        }
        send({ type: "xr", head: round(pose.transform.matrix), hands });
        state.xrSent += 1;
        last = t;
      }
      drawHead(gl, layer, pose, quad);
    };
    session.requestAnimationFrame(onFrame);
  }

  async function setupXr() {
    try {
      if (emulate) await loadEmulator();
      if (!navigator.xr || !(await navigator.xr.isSessionSupported("immersive-vr"))) return;
      const btn = $("btn-xr");
      btn.hidden = false;
      btn.addEventListener("click", () => startXr().catch((err) => { $("st-msg").textContent = `VR: ${err.message}`; }));
    } catch (err) {
      $("st-msg").textContent = `VR unavailable: ${err.message}`;
    }
  }
  setupXr();

  connect();
  // the controls are repeated every 0.1 s: the server releases them when the page goes quiet
  setInterval(() => { if (!state.xr) sendCommand(); }, 100);
})();
