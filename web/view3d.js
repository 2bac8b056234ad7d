// #/3d: the site model in 3D, the viewer `strata export viewer` writes (layers, unit
// solids, markers, finds, cameras; a section plane and a measuring tool), served by
// GET /api/viewer into a sandboxed iframe: its own scripts run there, apart from this
// page (no access to it or to the API's token).
import {api, showError} from './api.js';
import {el, replace, section} from './dom.js';

export const title = '3D';

export async function render(main, params, signal) {
  const layerChoice = el('select', {id: 'view3d-layer', name: 'layer'}, el('option', {value: ''}, 'the whole site'));
  const frame = el('iframe', {
    id: 'view3d-frame',
    title: 'The site model in 3D',
    sandbox: 'allow-scripts',
    referrerpolicy: 'no-referrer',
  });
  const status = el('p', {id: 'view3d-status', class: 'muted'}, 'Building the model…');
  replace(main,
    el('h1', {tabindex: -1}, 'The site in 3D'),
    section('Model', 'view3d-section',
      el('p', {class: 'hint'},
        'Drag to turn, scroll or pinch to zoom; the panel switches layers and units, moves a section plane and ' +
        'measures between two clicks (site CRS coordinates).'),
      el('div', {class: 'actions'}, el('label', {}, 'Show ', layerChoice)),
      status, frame));

  const show = (layer) => {
    status.textContent = 'Building the model…';
    frame.src = `/api/viewer${layer ? `?layer=${encodeURIComponent(layer)}` : ''}`;
  };
  frame.addEventListener('load', () => {
    status.textContent = 'Loaded.';
  });
  layerChoice.addEventListener('change', () => show(layerChoice.value));

  try {
    const layers = await api.get('/api/layers');
    if (signal.aborted) return;
    const dense = layers.filter((l) => l.dense);
    for (const l of dense) layerChoice.appendChild(el('option', {value: l.name}, `layer ${l.name}`));
    if (!dense.length) {
      status.textContent = 'No layer has a dense surface now: process a layer to its products first (its page, Process).';
      frame.hidden = true;
      return;
    }
    show('');
  } catch (err) {
    if (!signal.aborted) showError(err);
  }
}
