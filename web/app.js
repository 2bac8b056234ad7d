// The router: #/site, #/finds, #/map, #/3d, #/layer/NAME, #/markers/NAME (NAME URL-encoded). Each page is a
// module with render(main, params, signal); the signal aborts when the page is left
// (an open event stream closes, late answers are dropped).
import {clearMessage, showMessage} from './api.js';

const routes = [
  {pattern: /^#\/site$/, module: './site.js', nav: 'site'},
  {pattern: /^#\/finds$/, module: './finds.js', nav: 'finds'},
  {pattern: /^#\/map$/, module: './map.js', nav: 'map'},
  {pattern: /^#\/3d$/, module: './view3d.js', nav: '3d'},
  {pattern: /^#\/layer\/(.+)$/, module: './layer.js', nav: 'site', params: (m) => ({name: decode(m[1])})},
  {pattern: /^#\/markers\/(.+)$/, module: './markers.js', nav: 'site', params: (m) => ({name: decode(m[1])})},
];
const DEFAULT = '#/site';

function decode(s) {
  try {
    return decodeURIComponent(s);
  } catch {
    return s;
  }
}

let current = null;  // AbortController of the page shown

// keepMessage: the first load, or a redirect that has just said why.
async function route(keepMessage) {
  const hash = location.hash || DEFAULT;
  const found = routes.map((r) => ({r, m: hash.match(r.pattern)})).find((x) => x.m);
  if (!found) {
    showMessage(`There is no page ${hash}: showing the site.`, 'error');
    history.replaceState(null, '', DEFAULT);
    return route(true);
  }
  const {r, m} = found;
  if (current) current.abort();
  const controller = new AbortController();
  current = controller;
  if (!keepMessage) clearMessage();

  for (const a of document.querySelectorAll('nav a[data-nav]')) {
    if (a.dataset.nav === r.nav) a.setAttribute('aria-current', 'page');
    else a.removeAttribute('aria-current');
  }

  const main = document.getElementById('page');
  main.setAttribute('aria-busy', 'true');
  try {
    const page = await import(r.module);
    if (controller.signal.aborted) return;
    const params = r.params ? r.params(m) : {};
    document.title = `${params.name ? `${params.name} · ` : ''}${page.title} · strata field station`;
    const rendering = page.render(main, params, controller.signal);
    if (!keepMessage) main.querySelector('h1')?.focus();
    await rendering;
  } catch (err) {
    if (!controller.signal.aborted) showMessage(`The page could not be shown: ${err.message || err}`, 'error');
  } finally {
    if (current === controller) main.removeAttribute('aria-busy');
  }
}

// A tap on the message bar dismisses it.
document.getElementById('message').addEventListener('click', () => showMessage(''));
window.addEventListener('hashchange', () => route(false));
if (!location.hash) history.replaceState(null, '', DEFAULT);
route(true);
