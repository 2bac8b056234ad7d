// DOM helpers: every element is made with createElement and every piece of text
// goes in through textContent (a text node), never innerHTML, so what the project
// holds is shown as text whatever characters it contains.

// el('a', {href: '#/site', class: 'nav'}, 'Site'): attributes by setAttribute,
// except `on*` functions (event listeners) and a few live properties; children are
// nodes, strings/numbers (text nodes) or arrays of them; null/false/undefined skipped.
export function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === null || value === undefined || value === false) continue;
    if (key.startsWith('on') && typeof value === 'function') {
      node.addEventListener(key.slice(2).toLowerCase(), value);
    } else if (key === 'value' || key === 'checked' || key === 'selected') {
      node[key] = value;
    } else {
      node.setAttribute(key, value === true ? '' : String(value));
    }
  }
  append(node, children);
  return node;
}

function append(node, children) {
  for (const child of children) {
    if (child === null || child === undefined || child === false) continue;
    if (Array.isArray(child)) append(node, child);
    else if (child instanceof Node) node.appendChild(child);
    else node.appendChild(document.createTextNode(String(child)));
  }
}

// Replace all of node's children.
export function replace(node, ...children) {
  node.replaceChildren();
  append(node, children);
  return node;
}

// --- number and value formatting -------------------------------------------------

const DASH = '—';

// Coordinates and heights in metres: 3 decimals (millimetres).
export function coord(v) {
  return typeof v === 'number' && Number.isFinite(v) ? v.toFixed(3) : DASH;
}

export function count(v) {
  return typeof v === 'number' && Number.isFinite(v) ? String(Math.round(v)) : DASH;
}

// A figure of unknown kind: integers as they are, other numbers to 3 decimals.
export function figure(v) {
  if (typeof v === 'boolean') return v ? 'yes' : 'no';
  if (typeof v === 'number') return Number.isInteger(v) ? String(v) : coord(v);
  if (v === null || v === undefined || v === '') return DASH;
  return String(v);
}

export function percent(done, total) {
  if (!(total > 0)) return '';
  return `${Math.min(100, Math.floor((100 * done) / total))} %`;
}

export function duration(seconds) {
  if (!(seconds >= 0)) return '';
  const s = Math.round(seconds);
  if (s < 60) return `${s} s`;
  const m = Math.floor(s / 60);
  if (m < 60) return `${m} min ${String(s % 60).padStart(2, '0')} s`;
  return `${Math.floor(m / 60)} h ${String(m % 60).padStart(2, '0')} min`;
}

// ISO 8601 as the project holds it, shown with a space instead of the T.
export function when(iso) {
  return iso ? String(iso).replace('T', ' ') : DASH;
}

// A tick for a state flag, with words for screen readers and tests.
export function tick(flag) {
  return el('span', {class: flag ? 'tick yes' : 'tick no', title: flag ? 'yes' : 'no',
                     'aria-label': flag ? 'yes' : 'no', 'data-value': flag ? 'yes' : 'no'},
            flag ? '✓' : '–');
}

export function words(identifier) {
  return String(identifier ?? '').replaceAll('_', ' ');
}

// --- building blocks --------------------------------------------------------------

// A table in a horizontally scrolling wrapper. columns: [{label, cell(row) -> child,
// class?}]; an empty list shows `empty` in one row.
export function table(id, caption, columns, rows, empty = 'None yet.') {
  const head = el('tr', {}, columns.map((c) => el('th', {scope: 'col', class: c.class}, c.label)));
  const body = rows.length
    ? rows.map((row) => el('tr', {}, columns.map((c) => el('td', {class: c.class}, c.cell(row)))))
    : [el('tr', {class: 'empty'}, el('td', {colspan: columns.length}, empty))];
  return el('div', {class: 'table-wrap', tabindex: 0, role: 'region', 'aria-labelledby': `${id}-caption`},
            el('table', {id}, el('caption', {id: `${id}-caption`, class: 'visually-hidden'}, caption),
               el('thead', {}, head), el('tbody', {}, body)));
}

// A labelled form control; the control's name is the API field.
export function field(label, control, hint) {
  if (!control.id) control.id = `f-${control.name}-${Math.random().toString(36).slice(2, 8)}`;
  return el('div', {class: 'field'},
            el('label', {for: control.id}, label),
            control,
            hint ? el('small', {class: 'hint'}, hint) : null);
}

export function select(attrs, options, chosen) {
  return el('select', attrs,
            options.map((o) => {
              const value = typeof o === 'string' ? o : o.value;
              const label = typeof o === 'string' ? o : o.label;
              return el('option', {value, selected: value === chosen}, label);
            }));
}

// Refill a <select> with options, keeping the chosen value when it is still there.
export function setOptions(sel, values, placeholder) {
  const kept = sel.value;
  sel.replaceChildren();
  if (placeholder !== undefined) sel.appendChild(el('option', {value: ''}, placeholder));
  for (const v of values) sel.appendChild(el('option', {value: v}, v));
  if (values.includes(kept)) sel.value = kept;
}

export function section(title, id, ...children) {
  return el('section', {'aria-labelledby': `${id}-title`, class: 'panel'},
            el('h2', {id: `${id}-title`}, title), children);
}
