// The viewer page's script (plain JavaScript on the global THREE of three.js r111).
// Precision: the glTF nodes carry absolute translations (mesh nodes the local origin,
// markers and cameras their site position); every node is shifted by -origin in JS
// doubles, so the GPU sees float32 values of metres around zero, and coordinates are
// shown as origin + local, again in doubles.
namespace strata::cli {

extern const char* const kViewerJs;
const char* const kViewerJs = R"JS(
(function () {
  'use strict';
  var status = document.getElementById('status');
  function fail(msg) { status.textContent = 'error: ' + msg; status.className = 'error'; }
  window.addEventListener('error', function (e) { fail(e.message); });

  function decodeModel() {
    var text = document.getElementById('model').textContent.replace(/\s+/g, '');
    var bin = atob(text), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
    return bytes.buffer;
  }

  // WebGL may be missing (old GPU, headless browser): the model still loads and the
  // page says so instead of failing silently.
  function makeRenderer(view) {
    try {
      var r = new THREE.WebGLRenderer({ antialias: true });
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
  var layers = [], units = [], markers = [], cameras = [], pickable = [];

  function fmtCrs(p) {  // a local (three.js) point in site CRS coordinates, millimetres
    return 'E ' + (origin[0] + p.x).toFixed(3) + '  N ' + (origin[1] - p.z).toFixed(3) + '  Z ' +
      (origin[2] + p.y).toFixed(3);
  }

  function checkbox(parent, text, checked, onChange) {
    var label = document.createElement('label'), box = document.createElement('input');
    box.type = 'checkbox';
    box.checked = checked;
    box.addEventListener('change', function () { onChange(box.checked); });
    label.appendChild(box);
    label.appendChild(document.createTextNode(' ' + text));
    document.getElementById(parent).appendChild(label);
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
      if (name.indexOf('layer ') === 0) {
        layers.push(node);
        pickable.push(node);
        checkbox('layers', name.slice(6), true, function (on) { node.visible = on; });
      } else if (name.indexOf('unit ') === 0) {
        units.push(node);
        pickable.push(node);
        checkbox('units', name.slice(5), true, function (on) { node.visible = on; });
      } else if (name.indexOf('marker ') === 0) {
        var ball = new THREE.Mesh(new THREE.SphereGeometry(size * 0.006, 12, 8),
          new THREE.MeshLambertMaterial({ color: 0xd02020 }));
        node.add(ball);
        var label = document.createElement('div');
        label.className = 'label';
        label.textContent = name.slice(7);
        document.getElementById('labels').appendChild(label);
        markers.push({ node: node, label: label });
      } else if (name.indexOf('camera ') === 0) {
        node.add(cameraGlyph(size * 0.01));
        node.visible = false;
        cameras.push(node);
      }
    });
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
    }
    [on, pos, az].forEach(function (el) { el.addEventListener('input', update); el.addEventListener('change', update); });
    update();
  }

  var raycaster = new THREE.Raycaster(), mouse = new THREE.Vector2();
  function pick(event) {
    var rect = view.getBoundingClientRect();
    mouse.set((event.clientX - rect.left) / rect.width * 2 - 1, -(event.clientY - rect.top) / rect.height * 2 + 1);
    raycaster.setFromCamera(mouse, camera);
    var hits = raycaster.intersectObjects(pickable, true);
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

  // Two clicks: the site CRS coordinates of each point, then the 3D and horizontal
  // distance; a third click starts again. A drag (orbiting) is not a click.
  function setupMeasure(fit) {
    var readout = document.getElementById('readout'), points = [], glyphs = new THREE.Group(), down = null;
    scene.add(glyphs);
    view.addEventListener('pointerdown', function (e) { down = [e.clientX, e.clientY]; });
    view.addEventListener('pointerup', function (e) {
      if (!document.getElementById('measure').checked || !down) return;
      if (Math.abs(e.clientX - down[0]) + Math.abs(e.clientY - down[1]) > 4) return;
      var hit = pick(e);
      if (!hit) return;
      if (points.length === 2) { points = []; while (glyphs.children.length) glyphs.remove(glyphs.children[0]); }
      points.push(hit.point.clone());
      var ball = new THREE.Mesh(new THREE.SphereGeometry(fit.size * 0.003, 10, 6),
        new THREE.MeshBasicMaterial({ color: 0xff8800 }));
      ball.position.copy(hit.point);
      glyphs.add(ball);
      var text = points.map(function (p, i) { return 'P' + (i + 1) + '  ' + fmtCrs(p); }).join('\n');
      if (points.length === 2) {
        var d = points[1].clone().sub(points[0]);
        text += '\n3D ' + d.length().toFixed(3) + ' m   horizontal ' + Math.hypot(d.x, d.z).toFixed(3) + ' m' +
          '   dZ ' + d.y.toFixed(3) + ' m';
        var g = new THREE.BufferGeometry().setFromPoints(points);
        glyphs.add(new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0xff8800 })));
      }
      readout.textContent = text;
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
  function start(gltf) {
    var extras = (gltf.asset && gltf.asset.extras) || {};
    if (extras.origin) origin = extras.origin.slice();
    // glTF axes: x = E, y = Z, z = -N.
    var shift = new THREE.Vector3(-origin[0], -origin[2], origin[1]);
    var nodes = gltf.scene.children.slice();
    nodes.forEach(function (node) { node.position.add(shift); root.add(node); });
    var box = new THREE.Box3().setFromObject(root);
    if (box.isEmpty()) box.set(new THREE.Vector3(-1, -1, -1), new THREE.Vector3(1, 1, 1));
    var fit = fitView(box);
    sortNodes(nodes, fit.size);
    document.getElementById('show-markers').addEventListener('change', function (e) {
      markers.forEach(function (m) { m.node.visible = e.target.checked; });
      placeLabels();  // now, not at the next frame: a hidden tab draws none
    });
    document.getElementById('show-cameras').addEventListener('change', function (e) {
      cameras.forEach(function (c) { c.visible = e.target.checked; });
    });
    setupSection(fit);
    setupHover();
    setupMeasure(fit);
    var controls = new THREE.OrbitControls(camera, renderer ? renderer.domElement : view);
    controls.target.copy(fit.centre);
    controls.update();
    window.addEventListener('resize', function () {
      camera.aspect = view.clientWidth / view.clientHeight;
      camera.updateProjectionMatrix();
      if (renderer) renderer.setSize(view.clientWidth, view.clientHeight);
    });
    function frame() {
      controls.update();
      if (renderer) renderer.render(scene, camera);
      placeLabels();
      requestAnimationFrame(frame);
    }
    frame();
    status.textContent = 'loaded ' + nodes.length + ' nodes' + (renderer ? '' : ' (no WebGL: nothing is drawn)');
    status.setAttribute('data-webgl', renderer ? 'yes' : 'no');
  }

  try {
    new THREE.GLTFLoader().parse(decodeModel(), '', start, function (e) { fail(e.message || String(e)); });
  } catch (e) {
    fail(e.message);
  }
})();
)JS";

}  // namespace strata::cli
