// The viewer page's script (plain JavaScript on the global THREE of three.js r111).
// Precision: the glTF nodes carry absolute translations (mesh nodes the local origin,
// markers and cameras their site position); every node is shifted by -origin in JS
// doubles, so the GPU sees float32 values of metres around zero, and coordinates are
// shown as origin + local, again in doubles.
// Levels of detail: <script id="model"> holds the whole scene with the large layer
// meshes at a coarse level, shown as soon as it is decoded; <script id="model-detail">
// (after this script, so the page draws before the parser reaches it) holds those
// layers at full level, which replace the coarse ones once decoded.
// URL parameters: hide=NAME,NAME (nodes as the checkboxes name them, e.g. "layer L2")
// start switched off; shade=1 lights the layers (default: their photo colours as
// recorded, unlit).
namespace strata {

extern const char* const kViewerJs;
const char* const kViewerJs = R"JS(
(function () {
  'use strict';
  var status = document.getElementById('status');
  function fail(msg) { status.textContent = 'error: ' + msg; status.className = 'error'; }
  window.addEventListener('error', function (e) { fail(e.message); });

  var params = new URLSearchParams(window.location.search);
  var hidden = (params.get('hide') || '').split(',').map(function (s) { return s.trim(); });
  var kSnapPx = 8;  // a click this close to a marker's centre on the screen picks the marker
  // The detail element comes after this script: the model's element says whether it will.
  var hasDetail = document.getElementById('model').getAttribute('data-detail') === 'yes';
  if (params.get('shade') === '1') document.getElementById('shade-layers').checked = true;

  // The bytes of an embedded .glb; null when the page has no such element.
  function decodeModel(id) {
    var element = document.getElementById(id);
    if (!element) return null;
    var bin = atob(element.textContent.replace(/\s+/g, '')), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
    element.textContent = '';  // the text is no longer needed: free it
    return bytes.buffer;
  }

  // WebGL may be missing (old GPU, headless browser): the model still loads and the
  // page says so instead of failing silently.
  function makeRenderer(view) {
    try {
      var r = new THREE.WebGLRenderer({ antialias: true });
      // glTF colours are linear, the screen is sRGB: three.js r111 encodes its output
      // with gamma 2.2 (the sRGB curve within 1-2 grey levels of 8 bits).
      r.gammaOutput = true;
      r.gammaFactor = 2.2;
      r.setPixelRatio(window.devicePixelRatio);
      r.setSize(view.clientWidth || 800, view.clientHeight || 600);
      view.appendChild(r.domElement);
      return r;
    } catch (e) {
      return null;
    }
  }

  var view = document.getElementById('view');
  var renderer = makeRenderer(view);
  var scene = new THREE.Scene();
  scene.background = new THREE.Color(0xdde3e8);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x666655, 0.9));
  var sun = new THREE.DirectionalLight(0xffffff, 0.6);
  sun.position.set(1, 2, 1.5);
  scene.add(sun);
  var root = new THREE.Group();  // at the local origin: children hold metres around zero
  scene.add(root);
  var camera = new THREE.PerspectiveCamera(50, (view.clientWidth || 800) / (view.clientHeight || 600), 0.01, 1e5);
  var origin = [0, 0, 0];  // site CRS E, N, Z of the local origin, JS doubles
  var objects = {};  // node name -> the node in the scene (a layer's is replaced by its full level)
  var layerNames = [], markers = [], cameras = [];
  var level = 'coarse', levels = [];  // what is shown; the levels as they arrived (the test hook reads them)

  function fmtCrs(p) {  // a local (three.js) point in site CRS coordinates, millimetres
    return 'E ' + (origin[0] + p.x).toFixed(3) + '  N ' + (origin[1] - p.z).toFixed(3) + '  Z ' +
      (origin[2] + p.y).toFixed(3);
  }

  // Shown when not switched off by the URL's hide parameter.
  function checkbox(parent, text, name) {
    var node = objects[name], checked = hidden.indexOf(name) < 0;
    node.visible = checked;
    return addCheckbox(parent, text, checked, function (on) { objects[name].visible = on; });
  }

  function addCheckbox(parent, text, checked, onChange) {
    var label = document.createElement('label'), box = document.createElement('input');
    box.type = 'checkbox';
    box.checked = checked;
    box.addEventListener('change', function () { onChange(box.checked); requestFrame(); });
    label.appendChild(box);
    label.appendChild(document.createTextNode(' ' + text));
    document.getElementById(parent).appendChild(label);
    return box;
  }

  // A layer's colours are the photos' (vertex colours or texture): shown unlit they are
  // exactly what was recorded; lit (the "shade layers" box) the relief reads better.
  function photoMaterials(node) {
    var shade = document.getElementById('shade-layers').checked;
    node.traverse(function (o) {
      if (!o.isMesh) return;
      var lit = o.material;
      o.userData.litMaterial = lit;
      o.userData.photoMaterial = new THREE.MeshBasicMaterial({ color: lit.color, map: lit.map,
        vertexColors: lit.vertexColors, side: lit.side });
      o.material = shade ? lit : o.userData.photoMaterial;
    });
  }

  function faceCount(node) {
    var faces = 0;
    node.traverse(function (o) {
      if (!o.isMesh) return;
      var g = o.geometry;
      faces += (g.index ? g.index.count : g.attributes.position.count) / 3;
    });
    return faces;
  }

  function layerFaces() {
    return layerNames.reduce(function (n, name) { return n + faceCount(objects[name]); }, 0);
  }

  // A small pyramid at a camera node: apex at the centre, looking along -z.
  function cameraGlyph(size) {
    var s = size, h = size * 0.75, d = -size * 1.5, pts = [];
    var corners = [[-s, -h], [s, -h], [s, h], [-s, h]];
    for (var i = 0; i < 4; ++i) {
      var a = corners[i], b = corners[(i + 1) % 4];
      pts.push(0, 0, 0, a[0], a[1], d, a[0], a[1], d, b[0], b[1], d);
    }
    var g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(pts, 3));
    return new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: 0x2040a0 }));
  }

  function sortNodes(nodes, size) {
    nodes.forEach(function (node) {
      var name = node.userData.name || node.name;
      objects[name] = node;
      if (name.indexOf('layer ') === 0) {
        layerNames.push(name);
        photoMaterials(node);
        checkbox('layers', name.slice(6), name);
      } else if (name.indexOf('unit ') === 0) {
        checkbox('units', name.slice(5), name);
      } else if (name.indexOf('marker ') === 0) {
        var ball = new THREE.Mesh(new THREE.SphereGeometry(size * 0.006, 12, 8),
          new THREE.MeshLambertMaterial({ color: 0xd02020 }));
        node.add(ball);
        var label = document.createElement('div');
        label.className = 'label';
        label.textContent = name.slice(7);
        document.getElementById('labels').appendChild(label);
        markers.push({ node: node, label: label, name: name.slice(7), crs: node.userData.site_crs });
      } else if (name.indexOf('camera ') === 0) {
        node.add(cameraGlyph(size * 0.01));
        node.visible = false;
        cameras.push(node);
      }
    });
  }

  // The layers and unit solids the pointer can hit, as they are now (a layer's node is
  // replaced when its full level arrives).
  function pickable() {
    return Object.keys(objects).filter(function (name) {
      return name.indexOf('layer ') === 0 || name.indexOf('unit ') === 0;
    }).map(function (name) { return objects[name]; });
  }

  // Client pixel position of a local (three.js) point; null behind the camera.
  function screenPosition(p) {
    var rect = view.getBoundingClientRect(), q = p.clone().project(camera);
    if (q.z > 1) return null;
    return { x: rect.left + (q.x + 1) / 2 * rect.width, y: rect.top + (1 - q.y) / 2 * rect.height };
  }

  function fitView(box) {
    var centre = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3()).length() || 1;
    camera.position.copy(centre).add(new THREE.Vector3(0.4, 0.8, 0.9).multiplyScalar(size));
    camera.near = size / 1000;
    camera.far = size * 20;
    camera.updateProjectionMatrix();
    camera.lookAt(centre);
    return { centre: centre, size: size };
  }
)JS"
R"JS(
  // The vertical section: a clipping plane through the model's centre shifted along its
  // horizontal normal; azimuth 0 = normal to the north, clockwise.
  function setupSection(fit) {
    var plane = new THREE.Plane(new THREE.Vector3(1, 0, 0), 0);
    var on = document.getElementById('section'), pos = document.getElementById('section-pos');
    var az = document.getElementById('section-az');
    function update() {
      var a = Number(az.value) * Math.PI / 180;
      var n = new THREE.Vector3(Math.sin(a), 0, -Math.cos(a));  // (E, N) = (sin a, cos a)
      var p = fit.centre.clone().addScaledVector(n, Number(pos.value) * fit.size / 2);
      plane.setFromNormalAndCoplanarPoint(n, p);
      document.getElementById('az-deg').textContent = az.value;
      if (renderer) renderer.clippingPlanes = on.checked ? [plane] : [];
      requestFrame();
    }
    [on, pos, az].forEach(function (el) { el.addEventListener('input', update); el.addEventListener('change', update); });
    update();
  }

  var raycaster = new THREE.Raycaster(), mouse = new THREE.Vector2();
  function pick(event) {
    var rect = view.getBoundingClientRect();
    mouse.set((event.clientX - rect.left) / rect.width * 2 - 1, -(event.clientY - rect.top) / rect.height * 2 + 1);
    raycaster.setFromCamera(mouse, camera);
    var hits = raycaster.intersectObjects(pickable(), true);
    var planes = renderer ? renderer.clippingPlanes : [];
    for (var i = 0; i < hits.length; ++i) {  // the first hit that is visible and not clipped away
      var o = hits[i].object, shown = true;
      for (var q = o; q; q = q.parent) shown = shown && q.visible;
      var kept = planes.every(function (pl) { return pl.distanceToPoint(hits[i].point) >= 0; });
      if (shown && kept) return hits[i];
    }
    return null;
  }

  function unitOf(object) {
    for (var q = object; q; q = q.parent) if (q.userData && q.userData.unit !== undefined) return q.userData;
    return null;
  }

  function setupHover() {
    var tip = document.getElementById('tip');
    view.addEventListener('mousemove', function (event) {
      var hit = pick(event), u = hit ? unitOf(hit.object) : null;
      if (!u) { tip.style.display = 'none'; return; }
      tip.textContent = 'unit ' + u.unit + ': ' + u.volume_m3.toFixed(4) + ' m3 [' + u.interval_m3[0].toFixed(4) +
        ', ' + u.interval_m3[1].toFixed(4) + ']';
      tip.style.left = (event.clientX + 14) + 'px';
      tip.style.top = (event.clientY + 10) + 'px';
      tip.style.display = 'block';
    });
  }

  // The shown marker whose centre is within kSnapPx of the click on the screen, nearest
  // first; null when none is.
  function markerAt(event) {
    if (!document.getElementById('show-markers').checked) return null;
    camera.updateMatrixWorld();
    var best = null, bestDistance = kSnapPx;
    markers.forEach(function (m) {
      var s = screenPosition(m.node.getWorldPosition(new THREE.Vector3()));
      if (!s) return;
      var d = Math.hypot(s.x - event.clientX, s.y - event.clientY);
      if (d <= bestDistance) { best = m; bestDistance = d; }
    });
    return best;
  }

  // Two clicks: the site CRS coordinates of each point, then the 3D and horizontal
  // distance; a third click starts again. A drag (orbiting) is not a click. A click on
  // (or within kSnapPx of) a marker takes the marker's surveyed coordinates, as the
  // survey gave them, not a point of the surface.
  function setupMeasure(fit) {
    var readout = document.getElementById('readout'), points = [], glyphs = new THREE.Group(), down = null;
    scene.add(glyphs);
    view.addEventListener('pointerdown', function (e) { down = [e.clientX, e.clientY]; });
    view.addEventListener('pointerup', function (e) {
      if (!document.getElementById('measure').checked || !down) return;
      if (Math.abs(e.clientX - down[0]) + Math.abs(e.clientY - down[1]) > 4) return;
      var marker = markerAt(e), hit = marker ? null : pick(e);
      if (!marker && !hit) return;
      if (points.length === 2) { points = []; while (glyphs.children.length) glyphs.remove(glyphs.children[0]); }
      var p = marker ? { local: marker.node.getWorldPosition(new THREE.Vector3()), marker: marker }
        : { local: hit.point.clone(), marker: null };
      points.push(p);
      var ball = new THREE.Mesh(new THREE.SphereGeometry(fit.size * 0.003, 10, 6),
        new THREE.MeshBasicMaterial({ color: 0xff8800 }));
      ball.position.copy(p.local);
      glyphs.add(ball);
      var text = points.map(function (q, i) {
        if (!q.marker) return 'P' + (i + 1) + '  ' + fmtCrs(q.local);
        var c = q.marker.crs;
        return 'P' + (i + 1) + '  E ' + c[0].toFixed(3) + '  N ' + c[1].toFixed(3) + '  Z ' + c[2].toFixed(3) +
          '  marker ' + q.marker.name + ' (surveyed)';
      }).join('\n');
      if (points.length === 2) {
        var d = points[1].local.clone().sub(points[0].local);
        text += '\n3D ' + d.length().toFixed(3) + ' m   horizontal ' + Math.hypot(d.x, d.z).toFixed(3) + ' m' +
          '   dZ ' + d.y.toFixed(3) + ' m';
        var g = new THREE.BufferGeometry().setFromPoints([points[0].local, points[1].local]);
        glyphs.add(new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0xff8800 })));
      }
      readout.textContent = text;
      requestFrame();
    });
  }

  function placeLabels() {
    var w = view.clientWidth, h = view.clientHeight, show = document.getElementById('show-markers').checked;
    markers.forEach(function (m) {
      var p = m.node.getWorldPosition(new THREE.Vector3()).project(camera);
      var visible = show && p.z < 1;
      m.label.style.display = visible ? 'block' : 'none';
      if (visible) {
        m.label.style.left = ((p.x + 1) / 2 * w + 6) + 'px';
        m.label.style.top = ((1 - p.y) / 2 * h - 6) + 'px';
      }
    });
  }
)JS"
R"JS(
  // Frames are drawn on demand (a view change, a toggle, a new level), not in a loop: an
  // idle page costs nothing, and the parser reading the full level's element is not
  // slowed by redrawing a scene that has not changed (bench/viewer_load.py, headless
  // Chromium with SwiftShader: the full level of 977,202 faces drawn at 6.7 s with a
  // loop, at 1.6 s on demand).
  var framePending = false;
  function drawFrame() {
    if (renderer) renderer.render(scene, camera);
    placeLabels();
  }
  function requestFrame() {
    if (framePending) return;
    framePending = true;
    requestAnimationFrame(function () { framePending = false; drawFrame(); });
  }

  var shift = new THREE.Vector3();  // -origin in three.js axes (x = E, y = Z, z = -N), JS doubles

  function start(gltf) {
    var extras = (gltf.asset && gltf.asset.extras) || {};
    if (extras.origin) origin = extras.origin.slice();
    shift.set(-origin[0], -origin[2], origin[1]);
    var nodes = gltf.scene.children.slice();
    nodes.forEach(function (node) { node.position.add(shift); root.add(node); });
    var box = new THREE.Box3().setFromObject(root);
    if (box.isEmpty()) box.set(new THREE.Vector3(-1, -1, -1), new THREE.Vector3(1, 1, 1));
    var fit = fitView(box);
    sortNodes(nodes, fit.size);
    var showMarkers = document.getElementById('show-markers');
    function updateMarkers() {
      markers.forEach(function (m) { m.node.visible = showMarkers.checked; });
      placeLabels();  // now, not at the next frame: a hidden tab draws none
      requestFrame();
    }
    showMarkers.checked = hidden.indexOf('markers') < 0;
    showMarkers.addEventListener('change', updateMarkers);
    updateMarkers();
    document.getElementById('show-cameras').addEventListener('change', function (e) {
      cameras.forEach(function (c) { c.visible = e.target.checked; });
      requestFrame();
    });
    document.getElementById('shade-layers').addEventListener('change', function (e) {
      layerNames.forEach(function (name) {
        objects[name].traverse(function (o) {
          if (o.isMesh && o.userData.litMaterial) o.material = e.target.checked ? o.userData.litMaterial : o.userData.photoMaterial;
        });
      });
      requestFrame();
    });
    setupSection(fit);
    setupHover();
    setupMeasure(fit);
    var controls = new THREE.OrbitControls(camera, renderer ? renderer.domElement : view);
    controls.target.copy(fit.centre);
    controls.update();
    controls.addEventListener('change', requestFrame);
    window.addEventListener('resize', function () {
      camera.aspect = view.clientWidth / view.clientHeight;
      camera.updateProjectionMatrix();
      if (renderer) renderer.setSize(view.clientWidth, view.clientHeight);
      requestFrame();
    });
    drawFrame();
    loaded(nodes.length, hasDetail ? 'coarse' : 'full');
  }

  // The status box and the record of the levels: "loaded N nodes", while the full
  // level is still to come "(coarse level; full detail loading)".
  var nodeCount = 0;
  function loaded(nodes, shown) {
    nodeCount = nodes || nodeCount;
    level = shown;
    levels.push({ level: shown, ms: Math.round(performance.now()), layerFaces: layerFaces() });  // ms since the page began to load
    status.textContent = 'loaded ' + nodeCount + ' nodes' + (shown === 'coarse' ? ' (coarse level; full detail loading)' : '') +
      (renderer ? '' : ' (no WebGL: nothing is drawn)');
    status.setAttribute('data-webgl', renderer ? 'yes' : 'no');
    status.setAttribute('data-level', shown);
  }

  // The full level of the layers that were shown coarse: each node replaces its coarse
  // namesake, keeping whether it is switched on.
  function loadDetail() {
    var bytes = decodeModel('model-detail');
    if (!bytes) { fail('the full level of detail is missing from the page'); return; }
    new THREE.GLTFLoader().parse(bytes, '', function (gltf) {
      gltf.scene.children.slice().forEach(function (fresh) {
        var name = fresh.userData.name || fresh.name, old = objects[name];
        if (!old) return;
        fresh.position.add(shift);
        fresh.visible = old.visible;
        photoMaterials(fresh);
        root.remove(old);
        old.traverse(function (o) { if (o.isMesh) o.geometry.dispose(); });
        root.add(fresh);
        objects[name] = fresh;
      });
      // Recorded after the next frame, which uploads and draws the full level.
      requestFrame();
      requestAnimationFrame(function () { loaded(0, 'full'); });
    }, function (e) { fail(e.message || String(e)); });
  }

  // Test hook (tests/integration/model_export_test.cpp): where a named node ("marker
  // GCP1", "layer L1") is on the screen in client pixels (null: unknown or behind the
  // camera), the level shown, and the levels as they arrived with the layer faces drawn.
  window.strataViewer = {
    screenPositionOf: function (name) {
      var node = objects[name];
      if (!node) return null;
      scene.updateMatrixWorld();
      camera.updateMatrixWorld();
      return screenPosition(node.getWorldPosition(new THREE.Vector3()));
    },
    level: function () { return level; },
    levels: levels
  };

  try {
    new THREE.GLTFLoader().parse(decodeModel('model'), '', function (gltf) {
      start(gltf);
      if (level !== 'coarse') return;
      // After the coarse level's first frame, and once the parser has read the detail.
      var go = function () { requestAnimationFrame(function () { setTimeout(loadDetail, 0); }); };
      if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', go); else go();
    }, function (e) { fail(e.message || String(e)); });
  } catch (e) {
    fail(e.message);
  }
})();
)JS";

}  // namespace strata
