// #/finds: the finds of the site and the form that records one.
import {api, onSubmit, showError, showMessage} from './api.js';
import {el, replace, coord, table, field, setOptions, section} from './dom.js';

export const title = 'Finds';

export async function render(main, params, signal) {
  const list = el('div', {id: 'finds'}, 'Loading the finds…');
  const unit = el('select', {name: 'unit', required: true});
  const number = (name, label) =>
    field(label, el('input', {name, type: 'number', step: 'any', inputmode: 'decimal', required: true}));

  const form = el('form', {id: 'find-form', class: 'record', autocomplete: 'off'},
    field('Find id', el('input', {name: 'id', required: true, spellcheck: 'false'})),
    number('e', 'E (m)'),
    number('n', 'N (m)'),
    number('z', 'Z (m)'),
    field('Unit', unit),
    field('Type', el('input', {name: 'type', list: 'find-types', placeholder: 'pottery, bone, coin…'})),
    field('Description', el('input', {name: 'description'})),
    el('div', {class: 'actions'}, el('button', {type: 'submit', id: 'add-find'}, 'Add find')));
  const types = el('datalist', {id: 'find-types'});

  replace(main,
    el('h1', {tabindex: -1}, 'Finds'),
    section('Recorded finds', 'finds-section', list),
    section('Record a find', 'find-form-section',
      el('p', {class: 'hint'}, 'Coordinates in the site CRS, metres.'), form, types));

  const load = async () => {
    const [finds, units] = await Promise.all([api.get('/api/finds'), api.get('/api/units')]);
    if (signal.aborted) return;
    const codes = units.map((u) => u.code);
    setOptions(unit, codes, codes.length ? 'Choose a unit' : 'Record a unit first');
    const known = [...new Set(finds.map((f) => f.type).filter(Boolean))].sort();
    replace(types, known.map((t) => el('option', {value: t})));
    replace(list, table('finds-table', 'Finds', [
      {label: 'Id', cell: (f) => el('strong', {}, f.id)},
      {label: 'E (m)', cell: (f) => coord(f.e), class: 'num'},
      {label: 'N (m)', cell: (f) => coord(f.n), class: 'num'},
      {label: 'Z (m)', cell: (f) => coord(f.z), class: 'num'},
      {label: 'Unit', cell: (f) => f.unit || '—'},
      {label: 'Type', cell: (f) => f.type || '—'},
      {label: 'Description', cell: (f) => f.description || '', class: 'wide'},
    ], finds, 'No finds recorded yet.'));
  };

  onSubmit(form, async (body, f) => {
    await api.post('/api/finds', body);
    const keptUnit = unit.value;
    f.reset();
    unit.value = keptUnit;  // the next find is most often from the same unit
    showMessage(`Find ${body.id} recorded.`, 'ok');
    await load();
    f.elements.id.focus();
  });

  try {
    await load();
  } catch (err) {
    if (!signal.aborted) showError(err);
  }
}
