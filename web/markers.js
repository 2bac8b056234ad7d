// #/markers/NAME: the markers workspace of one layer. Each surveyed marker with its
// observations and residual; the photos that see it (a strip); one photo at any zoom
// with the survey's prediction and the observation drawn on it (photo-canvas.js). A
// click or a tap places the marker in full-image pixels; one key confirms, rejects or
// clears what strata predicted or detected. Guide predicts the clicked markers in the
// other photos; Georeference runs the alignment again and shows the RMSE against the
// one before.
import {api, enc, showError, showMessage} from './api.js';
import {ACTIVE, endMessage, followJob} from './jobs.js';
import {el, replace, tick, percent, duration} from './dom.js';
import {photoCanvas} from './photo-canvas.js';

export const title = 'Markers';

const STATUSES = ['clicked', 'confirmed', 'predicted', 'detected', 'rejected'];
const THUMB = 192;   // thumbnails' longer side, px
const CLOSE = 2;     // the zoom of `f` at least, CSS px per image pixel
const VERDICTS = {confirmed: 'confirmed', rejected: 'rejected', cleared: 'cleared'};
const STEP = 1.5;    // zoom buttons and keys

const finite = (v) => typeof v === 'number' && Number.isFinite(v);
const mm = (m) => (finite(m) ? `${(m * 1000).toFixed(1)} mm` : '—');
const mm1 = (m) => (finite(m) ? (m * 1000).toFixed(1) : '—');
const signedMm = (m) => (finite(m) ? `${m < 0 ? '−' : '+'}${Math.abs(m * 1000).toFixed(1)}` : '—');
const px = (v) => (finite(v) ? `${v.toFixed(2)} px` : '');
const plural = (n, word) => `${n} ${word}${n === 1 ? '' : 's'}`;

// The marker and photo chosen last in this layer, for this tab.
const memoryKey = (layer) => `strata.markers.${layer}`;
function recall(layer) {
  try {
    return JSON.parse(sessionStorage.getItem(memoryKey(layer))) || {};
  } catch {
    return {};
  }
}

// Scrolls a list (not the page) so that its item shows; the list is positioned, so the
// item's offsets are within it.
function scrollWithin(list, item) {
  const m = 8;
  if (item.offsetLeft < list.scrollLeft) list.scrollLeft = item.offsetLeft - m;
  else if (item.offsetLeft + item.offsetWidth > list.scrollLeft + list.clientWidth) {
    list.scrollLeft = item.offsetLeft + item.offsetWidth - list.clientWidth + m;
  }
  if (item.offsetTop < list.scrollTop) list.scrollTop = item.offsetTop - m;
  else if (item.offsetTop + item.offsetHeight > list.scrollTop + list.clientHeight) {
    list.scrollTop = item.offsetTop + item.offsetHeight - list.clientHeight + m;
  }
}

export async function render(main, params, signal) {
  const name = params.name;
  const base = `/api/layers/${enc(name)}`;
  const memory = recall(name);
  let overview = null;       // GET .../markers
  let detail = null;         // GET .../markers/{marker}
  let marker = memory.marker || null;
  let photo = memory.photo || null;
  let sticky = null;         // a photo acted on: kept in the strip although it no longer sees the marker
  let before = null;         // {control, check}: the RMSE before the georeference followed here
  let busy = false;          // a click or a verdict on its way
  let loads = 0;             // marker loads: a late answer is dropped
  let job = null;
  let stopJob = () => {};    // ends the following of the georeference job (jobs.js)

  // --- the page -------------------------------------------------------------------
  const state = el('dd', {id: 'layer-state'}, '…');
  const controlRmse = el('dd', {id: 'control-rmse', class: 'rmse'}, '…');
  const checkRmse = el('dd', {id: 'check-rmse', class: 'rmse'}, '…');
  const hint = el('p', {id: 'georef-hint', class: 'hint-box', hidden: true},
    'Not georeferenced yet: click at least 3 markers in 2 photos each, then Georeference.');
  const guideButton = el('button', {type: 'button', id: 'guide', class: 'secondary',
                                    title: 'Predict the clicked markers in the other photos that see them'}, 'Guide');
  const georefButton = el('button', {type: 'button', id: 'georeference',
                                     title: 'Run the alignment again (until sparse) with the markers'}, 'Georeference');
  const jobStage = el('span', {id: 'georef-stage'});
  const jobBar = el('progress', {max: 1, value: 0, 'aria-labelledby': 'georef-stage'});
  const jobFigures = el('span', {class: 'num'});
  const progress = el('p', {id: 'georef-progress', class: 'georef-progress', hidden: true, 'aria-live': 'polite'},
    jobStage, jobBar, jobFigures);
  const markerList = el('div', {id: 'marker-list', class: 'marker-list', role: 'group', 'aria-label': 'Markers'},
    'Loading the markers…');
  const markerTitle = el('span', {id: 'marker-title'});
  const allPhotos = el('input', {type: 'checkbox', id: 'all-photos'});
  const advance = el('input', {type: 'checkbox', id: 'advance', checked: true});
  const stripCount = el('p', {id: 'strip-count', class: 'muted'});
  const strip = el('div', {id: 'photo-strip', class: 'photo-strip', role: 'group', 'aria-label': 'Photos'});
  const view = photoCanvas({onPlace: (x, y) => place(x, y), onError: (err) => showError(err)});
  const photoStatus = el('p', {id: 'photo-status', class: 'photo-status'});
  const readout = el('p', {id: 'click-readout', class: 'readout', 'aria-live': 'polite'});
  const button = (id, text, cls, onclick, label) =>
    el('button', {type: 'button', id, class: cls, onclick, 'aria-label': label, title: label}, text);
  const reviewButtons = [
    button('confirm', 'Confirm', 'confirm', () => review('confirmed'), 'Confirm the observation (y or Enter)'),
    button('reject', 'Reject', 'reject', () => review('rejected'), 'Reject the observation (n or Delete)'),
    button('clear', 'Clear', 'secondary', () => review('cleared'), 'Clear the click, confirmation or rejection (u)')];
  const key = (k) => el('kbd', {}, k);

  replace(main, el('div', {class: 'markers-page'},
    el('p', {class: 'crumbs'}, el('a', {href: '#/site'}, 'Site'), ' › ',
      el('a', {id: 'layer-link', href: `#/layer/${enc(name)}`}, 'layer ', name), ' › markers'),
    el('h1', {tabindex: -1}, 'Markers of ', el('span', {id: 'layer-name'}, name)),
    el('section', {id: 'markers-summary', class: 'panel', 'aria-label': 'Georeference'},
      el('div', {class: 'summary-row'},
        el('dl', {class: 'facts'},
          el('div', {}, el('dt', {}, 'State'), state),
          el('div', {}, el('dt', {}, 'Control RMSE'), controlRmse),
          el('div', {}, el('dt', {}, 'Check RMSE'), checkRmse)),
        el('div', {class: 'actions'}, guideButton, georefButton)),
      hint,
      progress),
    el('div', {class: 'markers-workspace'},
      el('section', {class: 'panel marker-pane', 'aria-labelledby': 'marker-pane-title'},
        el('h2', {id: 'marker-pane-title'}, 'Markers'), markerList),
      el('section', {class: 'panel photo-pane', 'aria-labelledby': 'photo-pane-title'},
        el('div', {class: 'strip-bar'},
          el('h2', {id: 'photo-pane-title'}, 'Photos of ', markerTitle),
          el('label', {class: 'check'}, allPhotos, ' all photos')),
        stripCount, strip,
        el('div', {class: 'view-bar'},
          button('zoom-out', '−', 'secondary', () => view.zoomBy(1 / STEP), 'Zoom out (-)'),
          button('zoom-in', '+', 'secondary', () => view.zoomBy(STEP), 'Zoom in (+)'),
          button('zoom-fit', 'Fit', 'secondary', () => view.fit(), 'Fit the photo (0)'),
          photoStatus),
        view.node,
        el('div', {class: 'review-bar'}, reviewButtons,
          el('label', {class: 'check'}, advance, ' then the next photo')),
        readout,
        el('p', {id: 'key-help', class: 'key-help'},
          'Click or tap to place; drag to move; on touch, hold still to aim with the loupe and lift to place. ',
          el('span', {class: 'keys'}, 'Keys: ',
            key('y'), '/', key('Enter'), ' confirm · ', key('n'), '/', key('Delete'), ' reject · ', key('u'), ' clear · ',
            key('←'), key('→'), ' or ', key('k'), key('j'), ' photo · ', key('↑'), key('↓'), ' marker · ',
            key('+'), key('−'), key('0'), ' zoom · ', key('f'), ' go to the marker'))))));

  const remember = () => {
    try {
      sessionStorage.setItem(memoryKey(name), JSON.stringify({marker, photo}));
    } catch { /* private mode: not remembered */ }
  };

  // --- the overview: state, RMSE, markers -----------------------------------------
  const showRmse = (node, r, was) => {
    node.dataset.mm = r && finite(r.xyz_m) ? mm1(r.xyz_m) : '';
    replace(node,
      el('strong', {class: 'rmse-xyz'}, r ? mm(r.xyz_m) : '—'),
      was !== undefined ? el('span', {class: 'rmse-was'}, ` (was ${was ? mm(was.xyz_m) : 'none'})`) : null,
      r ? el('span', {class: 'rmse-axes'},
        `E ${mm1(r.e_m)} · N ${mm1(r.n_m)} · Z ${mm1(r.z_m)} mm · ${plural(r.markers ?? 0, 'marker')}`) : null);
  };

  const residualText = (r) => {
    if (!r) return 'no residual yet';
    if (r.triangulated === false) return 'not triangulated';
    return `dE ${signedMm(r.dE)} dN ${signedMm(r.dN)} dZ ${signedMm(r.dZ)} mm${finite(r.reprojection_px) ? ` · ${px(r.reprojection_px)}` : ''}`;
  };

  const showMarkers = () => {
    const markers = overview.markers || [];
    if (!markers.length) {
      replace(markerList, el('p', {class: 'muted'}, 'No surveyed markers: import the survey of the markers first.'));
      return;
    }
    replace(markerList, markers.map((m) => {
      const c = m.counts || {};
      const attrs = {type: 'button', class: 'marker-item', 'data-marker': m.name, 'data-role': m.role || '',
                     'aria-pressed': String(m.name === marker), onclick: () => selectMarker(m.name)};
      for (const k of STATUSES) attrs[`data-${k}`] = c[k] || 0;
      const shown = STATUSES.filter((k) => c[k] > 0);
      return el('button', attrs,
        el('span', {class: 'marker-head'}, el('span', {class: 'marker-name'}, m.name),
          el('span', {class: `role role-${m.role}`}, m.role || '')),
        el('span', {class: 'marker-counts'}, shown.length
          ? shown.map((k) => el('span', {class: `count status-${k}`, 'data-kind': k}, `${c[k]} ${k}`))
          : el('span', {class: 'muted'}, 'not placed yet')),
        el('span', {class: 'marker-residual', 'data-known': String(Boolean(m.residual))}, residualText(m.residual)));
    }));
  };

  const loadOverview = async () => {
    const o = await api.get(`${base}/markers`);
    if (signal.aborted) return;
    overview = o;
    replace(state,
      el('span', {class: 'flag-item', 'data-state': 'aligned'}, tick(o.aligned), ' aligned'),
      el('span', {class: 'flag-item', 'data-state': 'georeferenced'}, tick(o.georeferenced), ' georeferenced'));
    showRmse(controlRmse, o.control_rmse, before ? before.control : undefined);
    showRmse(checkRmse, o.check_rmse, before ? before.check : undefined);
    hint.hidden = Boolean(o.georeferenced);
    const names = (o.markers || []).map((m) => m.name);
    if (!names.includes(marker)) marker = names[0] || null;
    showMarkers();
  };

  // --- one marker: the strip ------------------------------------------------------
  const photos = () => (detail && Array.isArray(detail.photos) ? detail.photos : []);
  const entry = () => photos().find((p) => p.name === photo) || null;
  const seesKnown = () => Boolean(overview && overview.georeferenced) || photos().some((p) => p.sees);
  const visible = () => {
    if (allPhotos.checked || !seesKnown()) return photos();
    return photos().filter((p) => p.sees || p.observation || (p.status && p.status !== 'none') || p.name === sticky);
  };

  const thumbs = new Map();  // photo name -> {button, img, badge}: kept, so no thumbnail loads twice
  const thumbFor = (p) => {
    let t = thumbs.get(p.name);
    if (!t) {
      const k = THUMB / Math.max(p.width || THUMB, p.height || THUMB, 1);
      const img = el('img', {src: `${base}/photos/${enc(p.name)}?max=${THUMB}`, alt: '', loading: 'lazy',
                             decoding: 'async', width: Math.round((p.width || 4) * k) || null,
                             height: Math.round((p.height || 3) * k) || null});
      const badge = el('span', {class: 'status-badge'});
      const b = el('button', {type: 'button', class: 'thumb', 'data-photo': p.name, onclick: () => selectPhoto(p.name)},
        img, el('span', {class: 'thumb-name'}, p.name), badge);
      t = {button: b, img, badge};
      thumbs.set(p.name, t);
    }
    const status = p.status || 'none';
    t.button.dataset.status = status;
    t.button.dataset.sees = String(Boolean(p.sees));
    t.button.setAttribute('aria-pressed', String(p.name === photo));
    t.button.title = `${p.name}: ${status}${finite(p.residual_px) ? `, ${px(p.residual_px)}` : ''}${p.registered === false ? ', not aligned' : ''}`;
    t.button.classList.toggle('unregistered', p.registered === false);
    replace(t.badge, status, finite(p.residual_px) ? ` ${px(p.residual_px)}` : null);
    return t.button;
  };

  const showStrip = () => {
    const list = visible();
    const all = photos();
    markerTitle.textContent = marker || '—';
    allPhotos.disabled = !seesKnown();
    if (!marker) stripCount.textContent = '';
    else if (!seesKnown()) {
      stripCount.textContent = `All ${plural(all.length, 'photo')}: the layer is not georeferenced, so which of them see ${marker} is not known.`;
    } else {
      const seeing = all.filter((p) => p.sees).length;
      stripCount.textContent = `${seeing} of ${plural(all.length, 'photo')} see ${marker}${allPhotos.checked ? ' (all shown)' : ''}.` +
        (list.length ? '' : ' Tick “all photos” to place it in another.');
    }
    replace(strip, list.map(thumbFor));
  };

  const scrollToThumb = () => {
    const t = photo && thumbs.get(photo);
    if (t && t.button.parentNode === strip) scrollWithin(strip, t.button);
  };

  // --- one photo: the view --------------------------------------------------------
  const focusPoint = (e) => {
    if (e && e.observation && finite(e.observation.x)) return [e.observation.x, e.observation.y];
    return e && Array.isArray(e.predicted) ? e.predicted : null;
  };

  const showEntry = () => {
    const e = entry();
    for (const b of reviewButtons) b.disabled = !e;
    if (!e) {
      photoStatus.textContent = marker ? 'No photo chosen.' : '';
      return;
    }
    const parts = [`${e.name}: ${e.status || 'none'}`];
    if (finite(e.residual_px)) parts.push(px(e.residual_px));
    if (Array.isArray(e.predicted)) parts.push(`survey at ${e.predicted[0].toFixed(1)}, ${e.predicted[1].toFixed(1)}`);
    if (e.registered === false) parts.push('not aligned');
    photoStatus.textContent = parts.join(' · ');
    photoStatus.dataset.status = e.status || 'none';
  };

  // recentre: a new photo or marker was chosen (not a refresh after a click).
  const showPhoto = (recentre) => {
    const e = entry();
    const wasFitted = view.isFitted();
    const t = e && thumbs.get(e.name);
    const changed = view.setPhoto(e ? {key: e.name, url: `${base}/photos/${enc(e.name)}`, width: e.width,
                                       height: e.height, placeholder: t && t.img, label: e.name} : null);
    view.setMarks(e, marker);
    if (e && (changed || recentre)) {
      const f = focusPoint(e);
      if (!wasFitted && f) view.centreOn(f[0], f[1]);
      else view.fit();
    }
    for (const b of strip.children) b.setAttribute('aria-pressed', String(b.dataset.photo === photo));
    scrollToThumb();
    showEntry();
  };

  const loadMarker = async (recentre) => {
    const m = marker;
    const n = ++loads;
    if (!m) {
      detail = null;
      showStrip();
      showPhoto(recentre);
      return;
    }
    const d = await api.get(`${base}/markers/${enc(m)}`);
    if (signal.aborted || n !== loads) return;
    detail = d;
    const list = visible();
    if (!list.some((p) => p.name === photo)) photo = list.length ? list[0].name : null;
    remember();
    showStrip();
    showPhoto(recentre);
  };

  const refresh = async () => {
    try {
      await Promise.all([loadOverview(), loadMarker(false)]);
    } catch (err) {
      if (!signal.aborted) showError(err);
    }
  };

  const selectMarker = async (m) => {
    if (m === marker && detail) return;
    marker = m;
    sticky = null;
    for (const b of markerList.querySelectorAll('[data-marker]')) b.setAttribute('aria-pressed', String(b.dataset.marker === m));
    try {
      await loadMarker(true);
    } catch (err) {
      if (!signal.aborted) showError(err);
    }
  };

  const selectPhoto = (p) => {
    photo = p;
    remember();
    showPhoto(true);
  };

  const stepPhoto = (d) => {
    const list = visible();
    const i = list.findIndex((p) => p.name === photo);
    const next = list[i < 0 ? 0 : i + d];
    if (next) selectPhoto(next.name);
  };

  const stepMarker = (d) => {
    const list = overview ? overview.markers || [] : [];
    const i = list.findIndex((m) => m.name === marker);
    const next = list[i < 0 ? 0 : i + d];
    if (next) {
      selectMarker(next.name);
      const b = markerList.querySelector(`[data-marker="${CSS.escape(next.name)}"]`);
      if (b) scrollWithin(markerList, b);
    }
  };

  const goToMarker = () => {
    const f = focusPoint(entry());
    if (f) view.centreOn(f[0], f[1], Math.max(view.view().scale, CLOSE));
    else showMessage(`${marker || 'The marker'} has no position in this photo yet: click to place it.`, 'info');
  };

  // The server's answer to a click or a verdict: the photo's new entry.
  const update = (m, e) => {
    if (!detail || m !== marker || !e || !e.name) return;
    detail = {...detail, photos: photos().map((p) => (p.name === e.name ? e : p))};
    showStrip();
    showPhoto(false);
  };

  // --- placing and reviewing ------------------------------------------------------
  const place = async (x, y) => {
    const e = entry();
    const m = marker;
    if (!e || !m || busy) {
      view.clearPending();
      return;
    }
    busy = true;
    try {
      const r = await api.post(`${base}/markers/${enc(m)}/clicks`, {photo: e.name, x, y});
      if (signal.aborted) return;
      const o = r && r.observation && finite(r.observation.x) ? r.observation : {x, y};
      readout.dataset.x = String(o.x);
      readout.dataset.y = String(o.y);
      readout.textContent = `${m} in ${e.name} at ${o.x.toFixed(2)}, ${o.y.toFixed(2)} px`;
      sticky = e.name;
      update(m, r);
      await refresh();
    } catch (err) {
      view.clearPending();
      if (!signal.aborted) showError(err);
    } finally {
      busy = false;
    }
  };

  const review = async (verdict) => {
    const e = entry();
    const m = marker;
    if (!e || !m) {
      showMessage('Choose a marker and a photo first.', 'error');
      return;
    }
    if (busy) return;
    busy = true;
    try {
      const r = await api.post(`${base}/markers/${enc(m)}/review`, {photo: e.name, verdict});
      if (signal.aborted) return;
      delete readout.dataset.x;
      delete readout.dataset.y;
      readout.textContent = `${m} in ${e.name}: ${VERDICTS[verdict]}`;
      sticky = e.name;
      update(m, r);
      if (verdict !== 'cleared' && advance.checked && m === marker && photo === e.name) stepPhoto(1);
      await refresh();
    } catch (err) {
      if (!signal.aborted) showError(err);
    } finally {
      busy = false;
    }
  };

  allPhotos.addEventListener('change', () => {
    showStrip();
    scrollToThumb();
  });

  // --- keys -----------------------------------------------------------------------
  const typing = (t) => t instanceof Element &&
    Boolean(t.closest('textarea, select, [contenteditable]:not([contenteditable="false"]), ' +
                      'input:not([type="checkbox"]):not([type="radio"]):not([type="button"])'));
  document.addEventListener('keydown', (e) => {
    if (e.defaultPrevented || e.ctrlKey || e.metaKey || e.altKey || typing(e.target)) return;
    const onControl = e.target instanceof Element && e.target.closest('button, a, summary');
    const verdict = (v) => {
      if (!e.repeat) review(v);
    };
    switch (e.key) {
      case 'y': case 'Y': verdict('confirmed'); break;
      case 'Enter': if (onControl) return; verdict('confirmed'); break;
      case 'n': case 'N': case 'Delete': case 'Backspace': verdict('rejected'); break;
      case 'u': case 'U': verdict('cleared'); break;
      case 'ArrowRight': case 'j': case 'J': stepPhoto(1); break;
      case 'ArrowLeft': case 'k': case 'K': stepPhoto(-1); break;
      case 'ArrowDown': stepMarker(1); break;
      case 'ArrowUp': stepMarker(-1); break;
      case '+': case '=': view.zoomBy(STEP); break;
      case '-': case '_': view.zoomBy(1 / STEP); break;
      case '0': view.fit(); break;
      case 'f': case 'F': goToMarker(); break;
      default: return;
    }
    e.preventDefault();
  }, {signal});

  // --- guide and georeference -----------------------------------------------------
  guideButton.addEventListener('click', async () => {
    guideButton.disabled = true;
    try {
      const r = await api.post(`${base}/guide`, {});
      if (signal.aborted) return;
      const notes = (r.markers || []).filter((m) => m.message).map((m) => `${m.name}: ${m.message}`)
        .concat((r.left_out || []).map((c) => `${c}: clicked in one photo only, click it in another`));
      showMessage(`${plural(r.guided ?? 0, 'predicted position')}${notes.length ? ` (${notes.join('; ')})` : ''}.`, 'ok');
      await refresh();
    } catch (err) {
      if (!signal.aborted) showError(err);
    } finally {
      guideButton.disabled = false;
    }
  });

  const stopFollowing = () => stopJob();

  const showJob = (j) => {
    job = j;
    progress.hidden = false;
    progress.dataset.state = j.state;
    jobStage.textContent = `Georeference ${j.state}${j.stage ? `: ${j.stage}` : ''}`;
    georefButton.disabled = ACTIVE.has(j.state);
    if (j.total > 0) showProgress(j);
  };

  const showProgress = (p) => {
    if (p.stage) jobStage.textContent = `Georeference: ${p.stage}`;
    if (p.total > 0) {
      jobBar.max = p.total;
      jobBar.value = Math.min(p.done || 0, p.total);
    } else {
      jobBar.removeAttribute('value');  // indeterminate
    }
    jobFigures.textContent = [percent(p.done || 0, p.total), p.elapsed_s !== undefined ? duration(p.elapsed_s) : '']
      .filter(Boolean).join(' · ');
  };

  const finish = async (j) => {
    stopFollowing();
    showJob(j);
    if (j.state === 'done') {
      jobBar.value = jobBar.max;
      jobFigures.textContent = '100 %';
    }
    showMessage(...endMessage(`Georeference of ${name}`, j, 'see the log on the layer page'));
    await refresh();
  };

  const follow = (j) => {
    stopFollowing();
    showJob(j);
    stopJob = followJob(j, {
      onProgress: (p) => {
        if (job.state === 'queued') showJob({...job, state: 'running'});
        showProgress(p);
      },
      onEnd: finish,
    });
  };

  const snapshot = () => ({control: overview ? overview.control_rmse || null : null,
                           check: overview ? overview.check_rmse || null : null});

  georefButton.addEventListener('click', async () => {
    georefButton.disabled = true;
    try {
      const was = snapshot();
      const j = await api.post(`${base}/process`, {until: 'sparse'});
      if (signal.aborted) return;
      before = was;
      jobFigures.textContent = '';
      showProgress({done: 0, total: 0});
      showMessage(`Georeferencing ${name}: the alignment runs again with the markers.`, 'info');
      follow(j);
    } catch (err) {
      georefButton.disabled = Boolean(job && ACTIVE.has(job.state));
      if (!signal.aborted) showError(err);
    }
  });

  // --- open and close -------------------------------------------------------------
  const hooks = {
    view: () => ({...view.view(), photo, marker}),
    imageToClient: (x, y) => view.imageToClient(x, y),
    clientToImage: (x, y) => view.clientToImage(x, y),
  };
  window.strataMarkers = hooks;
  signal.addEventListener('abort', () => {
    stopFollowing();
    view.destroy();
    if (window.strataMarkers === hooks) delete window.strataMarkers;
  });

  try {
    await loadOverview();
    await loadMarker(true);
  } catch (err) {
    if (signal.aborted) return;
    replace(markerList, el('p', {class: 'muted'}, `The markers of ${name} could not be read.`));
    showError(err);
    return;
  }
  try {
    const jobs = await api.get('/api/jobs');
    if (signal.aborted) return;
    const mine = (jobs || []).find((j) => j.layer === name);  // newest first
    if (mine && ACTIVE.has(mine.state)) {
      before = snapshot();
      follow(mine);
    }
  } catch (err) {
    if (!signal.aborted) showError(err);
  }
}
