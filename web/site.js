// #/site: the site, its units, relations, Harris matrix, layers and markers, with
// the forms that record units, relations and layers.
import {api, onSubmit, showError, showMessage} from './api.js';
import {el, replace, coord, count, when, tick, words, table, field, select, setOptions, section} from './dom.js';

const UNIT_TYPES = ['deposit', 'cut', 'structure', 'interface'];
const RELATIONS = ['above', 'below', 'cuts', 'cut_by', 'fills', 'filled_by', 'abuts', 'same_as', 'contemporary_with'];

export const title = 'Site';

export async function render(main, params, signal) {
  const head = el('div', {id: 'site-header', class: 'site-header', 'aria-live': 'polite'}, 'Loading the site…');
  const units = el('div', {id: 'units'});
  const relations = el('div', {id: 'relations'});
  const matrix = el('div', {id: 'matrix', class: 'matrix'});
  const layers = el('div', {id: 'layers'});
  const markers = el('div', {id: 'markers'});
  const codes = el('datalist', {id: 'unit-codes'});
  const layerUnit = el('select', {name: 'unit', required: true});

  const unitForm = el('form', {id: 'unit-form', class: 'record', autocomplete: 'off'},
    field('Code', el('input', {name: 'code', required: true, autocapitalize: 'characters', spellcheck: 'false'})),
    field('Type', select({name: 'type'}, UNIT_TYPES, 'deposit')),
    field('Description', el('input', {name: 'description'})),
    el('div', {class: 'actions'}, el('button', {type: 'submit', id: 'add-unit'}, 'Add unit')));

  const relationForm = el('form', {id: 'relation-form', class: 'record', autocomplete: 'off'},
    field('Unit', el('input', {name: 'a', list: 'unit-codes', required: true, spellcheck: 'false'})),
    field('Relation', select({name: 'relation'}, RELATIONS.map((r) => ({value: r, label: words(r)})), 'above')),
    field('Unit', el('input', {name: 'b', list: 'unit-codes', required: true, spellcheck: 'false'})),
    el('div', {class: 'actions'}, el('button', {type: 'submit', id: 'add-relation'}, 'Add relation')));

  const layerForm = el('form', {id: 'layer-form', class: 'record', autocomplete: 'off'},
    field('Name', el('input', {name: 'name', required: true, spellcheck: 'false'})),
    field('Unit', layerUnit),
    field('Captured at (optional)', el('input', {name: 'captured_at', type: 'datetime-local',
                                                   title: 'optional: else the time in the photos'})),
    el('div', {class: 'actions'}, el('button', {type: 'submit', id: 'add-layer'}, 'Add layer')));

  replace(main,
    el('h1', {tabindex: -1}, 'Site'),
    head,
    section('Units', 'units-section', units, el('h3', {}, 'Record a unit'), unitForm),
    section('Relations', 'relations-section', relations, el('h3', {}, 'Record a relation'), relationForm, codes),
    section('Harris matrix', 'matrix-section', matrix),
    section('Layers', 'layers-section', layers, el('h3', {}, 'Record a layer'), layerForm),
    section('Markers', 'markers-section', markers));

  let matrixVersion = 0;
  const refreshMatrix = () => {
    const img = el('img', {id: 'matrix-image', alt: 'Harris matrix of the site’s units',
                           src: `/api/matrix?format=svg&v=${matrixVersion++}`});
    img.addEventListener('error', () => replace(matrix, el('p', {id: 'matrix-missing', class: 'muted'},
      'Graphviz not installed: the Harris matrix cannot be drawn (the relations above are still recorded).')));
    replace(matrix, el('div', {class: 'matrix-scroll', tabindex: 0}, img));
  };

  const load = async (what) => {
    const want = new Set(what);
    const [site, unitList, relationList, layerList, markerList] = await Promise.all([
      api.get('/api/site'),
      want.has('units') ? api.get('/api/units') : null,
      want.has('relations') ? api.get('/api/relations') : null,
      want.has('layers') ? api.get('/api/layers') : null,
      want.has('markers') ? api.get('/api/markers') : null,
    ]);
    if (signal.aborted) return;
    showSite(head, site);
    if (unitList) {
      showUnits(units, unitList);
      const all = unitList.map((u) => u.code);
      replace(codes, all.map((c) => el('option', {value: c})));
      setOptions(layerUnit, all, all.length ? 'Choose a unit' : 'Record a unit first');
    }
    if (relationList) showRelations(relations, relationList);
    if (layerList) showLayers(layers, layerList);
    if (markerList) showMarkers(markers, markerList);
    if (want.has('matrix')) refreshMatrix();
  };

  onSubmit(unitForm, async (body, form) => {
    await api.post('/api/units', body);
    form.reset();
    showMessage(`Unit ${body.code} recorded.`, 'ok');
    await load(['units', 'matrix']);
    form.elements.code.focus();
  });

  onSubmit(relationForm, async (body, form) => {
    const r = await api.post('/api/relations', body);
    form.elements.a.value = '';
    form.elements.b.value = '';
    const added = r && r.added === false ? 'already recorded' : 'recorded';
    showMessage(`${body.a} ${words(body.relation)} ${body.b}: ${added}.`, 'ok');
    await load(['relations', 'matrix']);
    form.elements.a.focus();
  });

  onSubmit(layerForm, async (body, form) => {
    // datetime-local gives YYYY-MM-DDTHH:MM[:SS]; the project keeps YYYY-MM-DDTHH:MM:SS.
    if (body.captured_at && body.captured_at.length === 16) body.captured_at += ':00';
    await api.post('/api/layers', body);
    form.reset();
    showMessage(`Layer ${body.name} recorded: open it to upload its photos.`, 'ok');
    await load(['layers', 'units']);
    form.elements.name.focus();
  });

  try {
    await load(['units', 'relations', 'layers', 'markers', 'matrix']);
  } catch (err) {
    if (!signal.aborted) showError(err);
  }
}

function showSite(node, site) {
  const s = site || {};
  const origin = Array.isArray(s.origin) ? s.origin.map(coord).join(', ') : '—';
  const stats = ['units', 'layers', 'photos', 'markers', 'finds'];
  replace(node,
    el('p', {class: 'site-name'}, el('strong', {id: 'site-name'}, s.name || 'Unnamed site')),
    el('dl', {class: 'facts'},
       el('div', {}, el('dt', {}, 'CRS'), el('dd', {id: 'site-crs'}, s.crs || '—')),
       el('div', {}, el('dt', {}, 'Origin (E, N, Z)'), el('dd', {id: 'site-origin'}, origin))),
    el('ul', {id: 'site-counts', class: 'counts'},
       stats.map((k) => el('li', {'data-count': k}, el('span', {class: 'n'}, count(s[k])), ' ', k))));
}

function showUnits(node, units) {
  replace(node, table('units-table', 'Units', [
    {label: 'Code', cell: (u) => el('strong', {}, u.code)},
    {label: 'Type', cell: (u) => u.type || '—'},
    {label: 'Description', cell: (u) => u.description || '', class: 'wide'},
    {label: 'Layers', cell: (u) => layerLinks(u.layers || [])},
  ], units, 'No units yet: record the first below.'));
}

function layerLinks(names) {
  if (!names.length) return '—';
  const out = [];
  names.forEach((n, i) => {
    if (i) out.push(', ');
    out.push(el('a', {href: `#/layer/${encodeURIComponent(n)}`}, n));
  });
  return out;
}

function showRelations(node, relations) {
  if (!relations.length) {
    replace(node, el('p', {id: 'relations-list', class: 'muted'}, 'No relations yet.'));
    return;
  }
  replace(node, el('ul', {id: 'relations-list', class: 'relations'},
    relations.map((r) => el('li', {'data-a': r.a, 'data-relation': r.relation, 'data-b': r.b},
      el('strong', {}, r.a), ' ', el('span', {class: 'rel'}, words(r.relation)), ' ', el('strong', {}, r.b)))));
}

function showLayers(node, layers) {
  replace(node, table('layers-table', 'Layers', [
    {label: 'Layer', cell: (l) => el('a', {href: `#/layer/${encodeURIComponent(l.name)}`}, l.name)},
    {label: 'Unit', cell: (l) => l.unit || '—'},
    {label: 'Captured', cell: (l) => when(l.captured_at), class: 'date'},
    {label: 'Photos', cell: (l) => count(Array.isArray(l.photos) ? l.photos.length : l.photos), class: 'num'},
    {label: 'Aligned', cell: (l) => tick(l.aligned), class: 'flag'},
    {label: 'Dense', cell: (l) => tick(l.dense), class: 'flag'},
    {label: 'Products', cell: (l) => tick(l.products), class: 'flag'},
  ], layers, 'No layers yet: record one below, then open it to upload photos.'));
}

function showMarkers(node, markers) {
  replace(node, table('markers-table', 'Markers', [
    {label: 'Name', cell: (m) => el('strong', {}, m.name)},
    {label: 'E (m)', cell: (m) => coord(m.e), class: 'num'},
    {label: 'N (m)', cell: (m) => coord(m.n), class: 'num'},
    {label: 'Z (m)', cell: (m) => coord(m.z), class: 'num'},
    {label: 'σ (m)', cell: (m) => coord(m.sigma_m ?? m.sigma), class: 'num'},
    {label: 'Role', cell: (m) => m.role || '—'},
  ], markers, 'No markers surveyed.'));
}
