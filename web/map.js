// #/map: the site in its own CRS (Leaflet's L.CRS.Simple in site-frame metres: lat =
// N - origin N, lng = E - origin E; never web Mercator, no online tiles). Per layer its
// orthophoto and DTM hillshade tiles cut by strata, contours and footprints; the
// markers and finds; the pointer's E, N; and the section tool: two clicks draw a line
// and the section along it (POST /api/sections) is shown below the map as an image.
import * as L from '/lib/leaflet/leaflet.esm.js';
import {api, enc, showError, showMessage} from './api.js';
import {el, replace, section} from './dom.js';

export const title = 'Map';

const COLOURS = ['#c0392b', '#2471a3', '#1e8449', '#b9770e', '#7d3c98', '#117a65'];

// A tooltip's content as a text node, never HTML.
function label(text) {
  return el('span', {}, text);
}

// Leaflet's layer control sets each name as innerHTML: the record's text (layer names,
// unit codes) goes in escaped, made by the browser from a text node, so it reads as
// the characters it holds.
function escaped(text) {
  return el('span', {}, text).innerHTML;
}

export async function render(main, params, signal) {
  const coords = el('output', {id: 'map-coords', class: 'map-coords'}, 'E —, N —');
  const tool = el('button', {type: 'button', id: 'section-tool', 'aria-pressed': 'false'}, 'Draw a section');
  const hint = el('span', {id: 'section-hint', class: 'muted'}, '');
  const mapBox = el('div', {id: 'map', class: 'site-map', 'aria-label': 'Map of the site'});
  const view = el('div', {id: 'section-view', class: 'section-view'},
                  el('p', {class: 'hint'}, 'Press “Draw a section”, then tap the two ends of the line on the map.'));
  replace(main,
    el('h1', {tabindex: -1}, 'Map'),
    el('div', {class: 'map-bar'}, tool, hint, coords),
    mapBox,
    section('Section', 'section-panel', view));

  let data;
  try {
    data = await api.get('/api/map');
  } catch (err) {
    if (!signal.aborted) showError(err);
    return;
  }
  if (signal.aborted) return;

  const [oE, oN] = data.origin;
  const ll = (e, n) => L.latLng(n - oN, e - oE);
  const site = (latlng) => ({e: latlng.lng + oE, n: latlng.lat + oN});
  const map = L.map(mapBox, {crs: L.CRS.Simple, minZoom: data.tiles.min_zoom, maxZoom: data.tiles.max_zoom,
                             zoomSnap: 0.25, attributionControl: false});
  signal.addEventListener('abort', () => map.remove(), {once: true});

  const overlays = {};
  const shown = [];
  let extent = null;
  const grow = (b) => {
    extent = extent ? extent.extend(b) : L.latLngBounds(b.getSouthWest(), b.getNorthEast());
  };
  const tiles = (layer, kind, raster) => {
    const bounds = L.latLngBounds(ll(raster.e_min, raster.n_min), ll(raster.e_max, raster.n_max));
    grow(bounds);
    return L.tileLayer(`/api/layers/${enc(layer.name)}/tiles/${kind}/{z}/{x}/{y}?v=${enc(raster.version)}`,
                       {bounds, tileSize: data.tiles.size_px, minZoom: data.tiles.min_zoom,
                        maxZoom: data.tiles.max_zoom, maxNativeZoom: data.tiles.max_zoom, noWrap: true,
                        className: `tiles-${kind}`});
  };
  const vectors = (collection, layer, style) => L.geoJSON(
    {type: 'FeatureCollection', features: collection.features.filter((f) => f.properties.layer === layer.name)},
    {coordsToLatLng: (c) => ll(c[0], c[1]), style});

  data.layers.forEach((layer, i) => {
    const colour = COLOURS[i % COLOURS.length];
    const name = escaped(`${layer.name} (unit ${layer.unit})`);
    if (layer.ortho) overlays[`${name}: orthophoto`] = tiles(layer, 'ortho', layer.ortho);
    if (layer.dtm) overlays[`${name}: hillshade`] = tiles(layer, 'hillshade', layer.dtm);
    overlays[`${name}: contours`] = vectors(data.contours, layer, {color: colour, weight: 1, opacity: 0.8});
    overlays[`${name}: footprint`] = vectors(data.footprints, layer, {color: colour, weight: 2, fill: false});
    if (i === data.layers.length - 1) {  // the latest layer shown at first
      shown.push(overlays[`${name}: ${layer.ortho ? 'orthophoto' : 'hillshade'}`], overlays[`${name}: footprint`]);
    }
  });

  const markers = L.layerGroup(data.markers.map((m) => {
    grow(L.latLngBounds(ll(m.e, m.n), ll(m.e, m.n)));
    return L.circleMarker(ll(m.e, m.n), {radius: 7, weight: 2, color: '#fff',
                                         fillColor: m.role === 'check' ? '#2471a3' : '#c0392b', fillOpacity: 0.9})
      .bindTooltip(label(`${m.name} (${m.role})`));
  }));
  const finds = L.layerGroup(data.finds.map((f) =>
    L.circleMarker(ll(f.e, f.n), {radius: 5, weight: 1, color: '#000', fillColor: '#f1c40f', fillOpacity: 1})
      .bindTooltip(label(`find ${f.id}${f.unit ? `, unit ${f.unit}` : ''}`))));
  overlays.Markers = markers;
  overlays.Finds = finds;
  shown.push(markers, finds);
  for (const layer of shown) layer.addTo(map);
  L.control.layers(null, overlays, {collapsed: window.matchMedia('(max-width: 700px)').matches}).addTo(map);
  L.control.scale({imperial: false}).addTo(map);
  if (extent) map.fitBounds(extent.pad(0.05));
  else map.setView([0, 0], 5);
  if (!data.layers.length) showMessage('No layer has products yet: process a layer to products to see it here.');
  if (data.truncated) showMessage('Some contour lines are left out: the map shows at most 60 000 vertices.');

  // The pointer's place; on a phone (no pointer hovering) the place last tapped.
  const readout = (e) => {
    const p = site(e.latlng);
    coords.textContent = `E ${p.e.toFixed(3)}, N ${p.n.toFixed(3)}`;
  };
  map.on('mousemove', readout);
  map.on('click', readout);

  // --- the section tool ------------------------------------------------------------
  const drawn = L.layerGroup().addTo(map);
  let ends = null;  // null: the tool is off; else the ends clicked so far
  let url = null;   // the object URL of the drawing shown
  signal.addEventListener('abort', () => url && URL.revokeObjectURL(url), {once: true});
  const setTool = (on) => {
    ends = on ? [] : null;
    tool.setAttribute('aria-pressed', on ? 'true' : 'false');
    mapBox.classList.toggle('picking', on);
    hint.textContent = on ? 'Tap the first end of the section.' : '';
  };
  tool.addEventListener('click', () => {
    drawn.clearLayers();
    setTool(ends === null);
  });

  const show = (blob, a, b) => {
    if (url) URL.revokeObjectURL(url);
    url = URL.createObjectURL(blob);
    replace(view,
      el('p', {}, `A (${a.e.toFixed(3)}, ${a.n.toFixed(3)}) → B (${b.e.toFixed(3)}, ${b.n.toFixed(3)})`),
      el('img', {src: url, alt: 'Section drawing along the line drawn on the map', class: 'section-drawing'}),
      el('p', {}, el('a', {id: 'section-download', href: url, download: 'section.svg'}, 'Download section.svg')));
  };

  map.on('click', async (e) => {
    if (ends === null) return;
    ends.push(e.latlng);
    L.circleMarker(e.latlng, {radius: 5, color: '#000', fillColor: '#fff', fillOpacity: 1}).addTo(drawn);
    if (ends.length === 1) {
      hint.textContent = 'Tap the other end.';
      return;
    }
    const [a, b] = ends.map(site);
    L.polyline(ends, {color: '#000', weight: 3, dashArray: '6 4'}).addTo(drawn);
    setTool(false);
    hint.textContent = 'Drawing the section…';
    tool.disabled = true;
    try {
      const blob = await api.postForBlob('/api/sections', {e1: a.e, n1: a.n, e2: b.e, n2: b.n});
      if (signal.aborted) return;
      show(blob, a, b);
      showMessage('');
    } catch (err) {
      if (!signal.aborted) showError(err);
    } finally {
      tool.disabled = false;
      hint.textContent = '';
    }
  });
}
