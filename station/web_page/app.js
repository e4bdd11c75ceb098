// revolve's web console: one page over the station's HTTP API (docs/web-console.md).
'use strict';
(function () {
  const $ = (id) => document.getElementById(id);
  const ACTIVE = ['homing', 'moving', 'settling', 'capturing', 'integrating', 'meshing', 'writing'];
  const ui = {
    scanId: '', stops: 0, done: new Set(), busy: false, lastStopsDone: -1,
    selected: '', events: 0, hullStopsIn: -1, hullLoading: false, hullWanted: false,
    modelUrl: '', viewer: null,
  };

  // ---- API ------------------------------------------------------------------------------------

  let loginWaiters = null;
  function login() {
    if (loginWaiters) return new Promise((resolve) => loginWaiters.push(resolve));
    loginWaiters = [];
    return new Promise((resolve) => {
      loginWaiters.push(resolve);
      const dialog = $('login');
      $('login-error').textContent = '';
      if (!dialog.open) dialog.showModal();
    });
  }
  $('login-form').addEventListener('submit', async (ev) => {
    ev.preventDefault();
    const res = await fetch('/api/login', {
      method: 'POST', credentials: 'same-origin',
      headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify({ token: $('token').value }),
    });
    if (!res.ok) { $('login-error').textContent = 'Wrong token.'; return; }
    $('login').close();
    $('token').value = '';
    const waiters = loginWaiters || [];
    loginWaiters = null;
    waiters.forEach((w) => w());
    connectEvents();
  });

  async function api(method, path, body) {
    const options = { method, credentials: 'same-origin', headers: {} };
    if (body !== undefined) {
      options.headers['Content-Type'] = 'application/json';
      options.body = JSON.stringify(body);
    }
    const res = await fetch(path, options);
    if (res.status === 401) { await login(); return api(method, path, body); }
    let data = null;
    try { data = await res.json(); } catch (e) { /* not JSON */ }
    if (!res.ok) {
      const err = new Error((data && data.error && data.error.message) || 'HTTP ' + res.status);
      err.status = res.status;
      throw err;
    }
    return data;
  }

  function say(text, error) {
    $('message').textContent = text || '';
    $('message').classList.toggle('error', !!error);
  }

  // ---- Status and events ----------------------------------------------------------------------

  function seconds(s) {
    if (s === null || s === undefined || !isFinite(s)) return '–';
    s = Math.max(0, Math.round(s));
    return s >= 60 ? Math.floor(s / 60) + ' min ' + (s % 60) + ' s' : s + ' s';
  }

  function drawStops() {
    const box = $('stops');
    if (box.childElementCount !== ui.stops) {
      box.textContent = '';
      for (let i = 0; i < ui.stops; i++) box.appendChild(document.createElement('span'));
    }
    [...box.children].forEach((cell, i) => {
      cell.classList.toggle('done', ui.done.has(i));
      cell.title = 'stop ' + (i + 1);
    });
  }

  // `e`: a scan event or the status (the same fields).
  function show(e, fromStatus) {
    if (e.scan_id !== undefined && e.scan_id !== ui.scanId) {
      ui.scanId = e.scan_id || '';
      ui.done = new Set();
      ui.hullStopsIn = -1;
      ui.lastStopsDone = -1;
    }
    ui.stops = e.stops || 0;
    const active = ACTIVE.includes(e.state);
    if (fromStatus) ui.busy = !!e.busy; else ui.busy = active;
    if (fromStatus || e.state === 'done') {
      for (let i = 0; i < (e.stops_done || 0); i++) ui.done.add(i);
    }
    if (e.state === 'integrating' && e.stop >= 0) ui.done.add(e.stop);
    drawStops();

    const badge = $('state');
    badge.textContent = e.state + (e.stop >= 0 ? ' · stop ' + (e.stop + 1) + '/' + e.stops : '');
    badge.dataset.state = e.state;
    badge.dataset.active = active;
    $('start').disabled = ui.busy;
    $('abort').disabled = !ui.busy;
    $('bar').style.width = (100 * (e.progress || 0)).toFixed(1) + '%';
    $('scan-id').textContent = ui.scanId || '–';
    $('stop').textContent = e.stop >= 0 ? (e.stop + 1) + ' / ' + e.stops : (e.stops_done || 0) + ' / ' + (e.stops || 0);
    $('eta').textContent = active ? seconds(e.eta_s) : '–';
    $('elapsed').textContent = seconds(e.elapsed_s);
    if (e.note) say(e.note, e.state === 'failed');
    if (e.error && e.error.message) say(e.error.message, true);

    if (e.stops_done !== ui.lastStopsDone) {
      ui.lastStopsDone = e.stops_done;
      if (e.stops_done > 0 && ui.scanId) { refreshFrame(); wantHull(); }
    }
    if (!fromStatus && ['done', 'failed', 'aborted'].includes(e.state)) {
      loadScans().then(() => { if (e.state === 'done') selectScan(ui.scanId); });
    }
  }

  let events = null;
  function connectEvents() {
    if (events) events.close();
    events = new EventSource('/api/events');
    events.addEventListener('status', (m) => {
      const s = JSON.parse(m.data);
      fillRecipes(s.daemon);
      show(s, true);
      $('conn').textContent = '';
    });
    events.addEventListener('scan', (m) => {
      ui.events++;
      show(JSON.parse(m.data), false);
      $('conn').textContent = '';
    });
    events.onerror = () => {
      $('conn').textContent = 'reconnecting…';
      // A stream refused for want of a token: ask for it once.
      api('GET', '/api/status').catch(() => {});
    };
  }

  function fillRecipes(daemon) {
    if (!daemon || !daemon.recipes) return;
    const select = $('recipe');
    if (select.childElementCount === daemon.recipes.length) return;
    select.textContent = '';
    daemon.recipes.forEach((r) => {
      const o = document.createElement('option');
      o.value = o.textContent = r;
      if (r === daemon.default_recipe) o.selected = true;
      select.appendChild(o);
    });
  }

  // ---- Buttons --------------------------------------------------------------------------------

  async function start(body) {
    try {
      const r = await api('POST', '/api/scans', body);
      say('Scan ' + r.scan + ' started.');
    } catch (e) { say(e.message, true); }
  }
  $('start').addEventListener('click', () => start({ recipe: $('recipe').value || undefined }));
  $('abort').addEventListener('click', async () => {
    try { await api('POST', '/api/abort'); say('Abort requested.'); } catch (e) { say(e.message, true); }
  });

  // ---- Live frame and hull --------------------------------------------------------------------

  function refreshFrame() {
    const img = $('frame');
    img.onload = () => { img.hidden = false; $('frame-none').hidden = true; };
    img.src = '/api/live/frame.jpg?scan=' + encodeURIComponent(ui.scanId) + '&n=' + ui.lastStopsDone;
    $('frame-caption').textContent = 'stop ' + ui.lastStopsDone + ' of ' + ui.stops;
  }

  function wantHull() {
    ui.hullWanted = true;
    if (!ui.hullLoading) loadHull(0);
  }

  // The hull is meshed after each stop on the station's own thread: ask again until it has the
  // stops the page has seen.
  async function loadHull(tries) {
    if (!ui.viewer) return;
    ui.hullLoading = true;
    ui.hullWanted = false;
    try {
      const res = await fetch('/api/live/hull.glb', { credentials: 'same-origin' });
      if (res.ok && res.headers.get('X-Revolve-Scan') === ui.scanId) {
        const stopsIn = Number(res.headers.get('X-Revolve-Stops-In'));
        if (stopsIn !== ui.hullStopsIn && ACTIVE.includes($('state').dataset.state)) {
          ui.hullStopsIn = stopsIn;
          const gltf = await parseGlb(await res.arrayBuffer());
          ui.viewer.show(gltf.scene, 0x4a90d9);
          ui.modelUrl = '';
          $('viewer-caption').textContent = 'live hull, ' + stopsIn + ' stops';
        }
        if (stopsIn < ui.lastStopsDone && tries < 20) ui.hullWanted = true;
      }
    } catch (e) { /* the next stop tries again */ }
    ui.hullLoading = false;
    if (ui.hullWanted) setTimeout(() => loadHull(tries + 1), 250);
  }

  function parseGlb(buffer) {
    return new Promise((resolve, reject) => new THREE.GLTFLoader().parse(buffer, '', resolve, reject));
  }

  // ---- The 3D viewer (three.js from the station: Debian's libjs-three) ------------------------

  function makeViewer() {
    const none = $('viewer-none');
    if (!window.THREE || !THREE.OrbitControls || !THREE.GLTFLoader) {
      none.hidden = false;
      none.textContent = 'No 3D view: three.js is not installed on the station (apt install libjs-three).';
      $('viewer-box').hidden = true;
      return null;
    }
    const canvas = $('viewer');
    let renderer;
    try {
      renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    } catch (e) {
      none.hidden = false;
      none.textContent = 'No 3D view: this browser has WebGL turned off.';
      $('viewer-box').hidden = true;
      return null;
    }
    const background = new THREE.Color(0x20242b);
    renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    const scene = new THREE.Scene();
    scene.background = background;
    scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 0.9));
    const sun = new THREE.DirectionalLight(0xffffff, 0.8);
    sun.position.set(1, 2, 1.5);
    scene.add(sun);
    const camera = new THREE.PerspectiveCamera(40, 4 / 3, 0.001, 100);
    camera.position.set(0.25, 0.2, 0.3);
    const controls = new THREE.OrbitControls(camera, canvas);
    controls.enableDamping = true;
    let current = null;

    function resize() {
      const w = canvas.clientWidth, h = canvas.clientHeight;
      if (w === 0 || h === 0) return;
      renderer.setSize(w, h, false);
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
    }
    new ResizeObserver(resize).observe(canvas);
    resize();
    (function animate() {
      requestAnimationFrame(animate);
      controls.update();
      renderer.render(scene, camera);
    })();

    return {
      // Shows `object` (the previous one goes), framed; `color` paints meshes without colours.
      show(object, color) {
        if (current) scene.remove(current);
        const firstFrame = current === null;
        current = object;
        if (color !== undefined) {
          object.traverse((o) => {
            if (o.isMesh && !o.geometry.attributes.color && !(o.material && o.material.map)) {
              o.material = new THREE.MeshStandardMaterial({ color, roughness: 0.8, metalness: 0 });
            }
          });
        }
        scene.add(object);
        const box = new THREE.Box3().setFromObject(object);
        const size = box.getSize(new THREE.Vector3()).length() || 0.1;
        const centre = box.getCenter(new THREE.Vector3());
        if (firstFrame || color === undefined) {
          camera.position.copy(centre).add(new THREE.Vector3(0.9, 0.6, 1.1).multiplyScalar(size));
          camera.near = size / 100;
          camera.far = size * 100;
          camera.updateProjectionMatrix();
        }
        controls.target.copy(centre);
      },
      // For tests: how many pixels differ from the background.
      pixels() {
        renderer.render(scene, camera);
        const gl = renderer.getContext();
        const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
        const px = new Uint8Array(w * h * 4);
        gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
        const bg = [background.r * 255, background.g * 255, background.b * 255];
        let differ = 0;
        for (let i = 0; i < px.length; i += 4) {
          if (Math.abs(px[i] - bg[0]) + Math.abs(px[i + 1] - bg[1]) + Math.abs(px[i + 2] - bg[2]) > 24) differ++;
        }
        return { width: w, height: h, differ, model: !!current };
      },
    };
  }

  // ---- Scans, report, downloads ---------------------------------------------------------------

  function fileUrl(id, path) {
    return '/api/scans/' + encodeURIComponent(id) + '/files/' + path.split('/').map(encodeURIComponent).join('/');
  }

  async function loadScans() {
    let list;
    try { list = await api('GET', '/api/scans'); } catch (e) { return; }
    const ul = $('scans');
    ul.textContent = '';
    list.scans.slice().reverse().forEach((s) => {
      const li = document.createElement('li');
      li.dataset.id = s.id;
      li.classList.toggle('selected', s.id === ui.selected);
      const img = document.createElement('img');
      img.alt = '';
      img.loading = 'lazy';
      if (s.contact_sheet) img.src = fileUrl(s.id, 'contact_sheet.png');
      const meta = document.createElement('div');
      meta.className = 'meta';
      meta.innerHTML = '<b></b><br><span class="muted"></span>';
      meta.querySelector('b').textContent = s.id;
      meta.querySelector('span').textContent =
          s.state + ' · ' + s.stops_done + '/' + s.stops + ' stops · ' + s.recipe;
      li.append(img, meta);
      if (['interrupted', 'aborted', 'failed'].includes(s.state)) {
        const resume = document.createElement('button');
        resume.textContent = 'Resume';
        resume.addEventListener('click', (ev) => { ev.stopPropagation(); start({ resume: s.id }); });
        li.append(resume);
      }
      li.addEventListener('click', () => selectScan(s.id));
      ul.appendChild(li);
    });
  }

  const FIGURES = [
    ['vertices', 'vertices', ''], ['triangles', 'triangles', ''],
    ['dimensions_mm', 'size', 'mm'], ['dimensions_px', 'size', 'px'],
    ['volume_mm3', 'volume', 'mm³'], ['volume_px3', 'volume', 'px³'],
    ['surface_area_mm2', 'surface', 'mm²'], ['surface_area_px2', 'surface', 'px²'],
    ['watertight', 'watertight', ''],
  ];

  function number(v) {
    if (typeof v !== 'number') return String(v);
    return Math.abs(v) >= 100 ? v.toFixed(0) : v.toPrecision(3);
  }

  function showReport(id, detail) {
    const dl = $('report');
    dl.textContent = '';
    const add = (name, value) => {
      const dt = document.createElement('dt'); dt.textContent = name;
      const dd = document.createElement('dd'); dd.textContent = value;
      dl.append(dt, dd);
    };
    const report = detail.report;
    const manifest = detail.manifest || {};
    add('state', manifest.state + ' · ' + manifest.stops_done + '/' + manifest.stops_planned + ' stops');
    if (report && report.model) {
      FIGURES.forEach(([key, name, unit]) => {
        const v = report.model[key];
        if (v === undefined) return;
        add(name, (Array.isArray(v) ? v.map(number).join(' × ') : number(v)) + (unit ? ' ' + unit : ''));
      });
      if (report.accuracy && report.accuracy.mean_surface_distance_mm !== undefined) {
        add('mean error', number(report.accuracy.mean_surface_distance_mm) + ' mm');
      }
      if (report.times_ms) add('time', seconds(report.times_ms.total_ms / 1000));
      if (report.quality_warnings) add('warnings', report.quality_warnings.length);
    }
    const links = $('downloads');
    links.textContent = '';
    const files = (manifest.model || []).concat(['report.json', 'manifest.json', 'contact_sheet.png']);
    files.forEach((f) => {
      if (f === 'report.json' && !report) return;
      const a = document.createElement('a');
      a.href = fileUrl(id, f) + '?download=1';
      a.textContent = f.split('/').pop();
      links.appendChild(a);
    });
    $('report-scan').textContent = id;
    $('report-card').hidden = false;
  }

  async function selectScan(id) {
    if (!id) return;
    ui.selected = id;
    document.querySelectorAll('#scans li').forEach((li) => li.classList.toggle('selected', li.dataset.id === id));
    let detail;
    try { detail = await api('GET', '/api/scans/' + encodeURIComponent(id)); } catch (e) { say(e.message, true); return; }
    showReport(id, detail);
    const glb = ((detail.manifest && detail.manifest.model) || []).find((f) => f.endsWith('.glb'));
    if (!ui.viewer) return;
    if (!glb) {
      $('viewer-caption').textContent = id + ': no glb model (add "glb" to [reconstruct] formats)';
      return;
    }
    const url = fileUrl(id, glb);
    if (url === ui.modelUrl) return;
    ui.modelUrl = url;
    new THREE.GLTFLoader().load(url, (gltf) => {
      ui.viewer.show(gltf.scene);
      $('viewer-caption').textContent = id;
    }, undefined, () => { $('viewer-caption').textContent = id + ': the model could not be loaded'; });
  }

  // ---- Start ----------------------------------------------------------------------------------

  ui.viewer = makeViewer();
  window.revolve = {
    ui,
    viewerPixels: () => (ui.viewer ? ui.viewer.pixels() : null),
  };
  api('GET', '/api/status').then((s) => {
    fillRecipes(s.daemon);
    show(s, true);
    connectEvents();
    return loadScans();
  }).then(() => {
    const first = document.querySelector('#scans li');
    if (first && !ui.busy) selectScan(first.dataset.id);
  }).catch((e) => say(e.message, true));
})();
