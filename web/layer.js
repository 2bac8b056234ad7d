// #/layer/NAME: one layer: its photos and their upload, its processing as a job
// followed live, and its verdict (is it recorded well enough to dig away?).
import {api, enc, showError, showMessage} from './api.js';
import {ACTIVE, endMessage, followJob} from './jobs.js';
import {el, replace, count, figure, coord, percent, duration, when, tick, words, field, select, section} from './dom.js';

const LOG_LINES = 50;

export const title = 'Layer';

export async function render(main, params, signal) {
  const name = params.name;
  const base = `/api/layers/${enc(name)}`;
  let layer = null;
  let present = new Set();  // photo names already in the layer
  let job = null;
  let stopJob = () => {};   // ends the following of the job followed (jobs.js)

  // --- the page -------------------------------------------------------------------
  const summary = el('div', {id: 'layer-summary', 'aria-live': 'polite'}, 'Loading the layer…');
  const photoCount = el('p', {id: 'photo-count'});
  const photoList = el('ol', {id: 'photo-list', class: 'photo-list'});
  const files = el('input', {type: 'file', id: 'photo-files', name: 'photos', multiple: true, accept: 'image/*'});
  const uploadButton = el('button', {type: 'button', id: 'upload'}, 'Upload');
  const uploads = el('ul', {id: 'uploads', class: 'uploads', 'aria-live': 'polite'});
  const until = select({name: 'until', id: 'until'},
                       [{value: 'products', label: 'products (DTM, orthophoto)'},
                        {value: 'dense', label: 'dense cloud'}, {value: 'sparse', label: 'sparse (alignment only)'}],
                       'products');
  const processButton = el('button', {type: 'submit', id: 'process'}, 'Process');
  const cancelButton = el('button', {type: 'button', id: 'cancel', class: 'secondary', disabled: true}, 'Cancel');
  const jobState = el('span', {id: 'job-state', class: 'state'}, 'no job');
  const jobMessage = el('p', {id: 'job-message', class: 'job-message'});
  const jobStage = el('span', {id: 'job-stage'});
  const jobProgress = el('progress', {id: 'job-progress', max: 1, value: 0, 'aria-labelledby': 'job-stage'});
  const jobPercent = el('span', {id: 'job-percent', class: 'num'});
  const jobElapsed = el('span', {id: 'job-elapsed', class: 'muted'});
  const jobLog = el('ol', {id: 'job-log', class: 'log', 'aria-live': 'off'});
  const verdict = el('div', {id: 'verdict', class: 'verdict'});
  // The field report itself (its coverage map, plans and figures), shown as it is: a
  // frame with no scripts and no access to this page.
  const reportFrame = el('iframe', {id: 'report-frame', title: 'The field report', sandbox: '', referrerpolicy: 'no-referrer'});
  const reportBox = el('details', {id: 'report-box', open: true, hidden: true},
    el('summary', {}, 'The field report: coverage map, plans, figures'), reportFrame);
  const quality = el('div', {id: 'quality'});
  const jobBox = el('div', {class: 'job idle', id: 'job'},
    el('p', {}, 'Job: ', jobState), jobMessage,
    el('div', {class: 'job-bar'}, jobStage, jobProgress, el('span', {class: 'job-figures'}, jobPercent, ' ', jobElapsed)),
    el('details', {class: 'log-box'}, el('summary', {}, 'Log'), jobLog));
  const processForm = el('form', {id: 'process-form', class: 'inline'},
    field('Until', until), el('div', {class: 'actions'}, processButton, cancelButton));

  replace(main,
    el('p', {class: 'crumbs'}, el('a', {href: '#/site'}, 'Site'), ' › layer'),
    el('div', {class: 'title-row'},
      el('h1', {tabindex: -1}, 'Layer ', el('span', {id: 'layer-name'}, name)),
      el('a', {id: 'markers-link', class: 'button-link', href: `#/markers/${enc(name)}`}, 'Markers')),
    summary,
    section('Photos', 'photos-section', photoCount, el('div', {class: 'scroll-box', tabindex: 0}, photoList),
      el('h3', {}, 'Upload photos'),
      el('p', {class: 'hint'}, 'Photos already in the layer are skipped; after an interruption, choose the same photos and press Upload again.'),
      el('div', {class: 'upload-row'}, field('Photos', files), el('div', {class: 'actions'}, uploadButton)),
      uploads),
    section('Processing', 'process-section', processForm, jobBox),
    section('Verdict', 'verdict-section', verdict, quality,
      el('p', {}, el('a', {id: 'report-link', href: `${base}/report`, target: '_blank', rel: 'noopener'}, 'Open the field report')),
      reportBox));

  // --- the layer ------------------------------------------------------------------
  const reload = async () => {
    layer = await api.get(base);
    if (signal.aborted) return;
    const photos = Array.isArray(layer.photo_list) ? layer.photo_list : [];  // `photos` is their count
    present = new Set(photos.map((p) => p.name));
    const q = layer.quality && typeof layer.quality === 'object' ? layer.quality : {};
    const flag = (k) => Boolean(layer[k] ?? q[k]);
    replace(summary, el('dl', {class: 'facts'},
      el('div', {}, el('dt', {}, 'Unit'), el('dd', {id: 'layer-unit'}, layer.unit || '—')),
      el('div', {}, el('dt', {}, 'Captured'), el('dd', {}, when(layer.captured_at))),
      el('div', {}, el('dt', {}, 'Photos'), el('dd', {}, count(photos.length))),
      el('div', {id: 'layer-state'},
         el('dt', {}, 'State'),
         el('dd', {}, ['aligned', 'dense', 'products'].map((k) =>
           el('span', {class: 'flag-item', 'data-state': k}, tick(flag(k)), ' ', k))))));
    photoCount.textContent = photos.length === 1 ? '1 photo' : `${photos.length} photos`;
    replace(photoList, photos.map((p) => el('li', {'data-name': p.name},
      el('span', {class: 'photo-name'}, p.name),
      p.width && p.height ? el('span', {class: 'muted'}, ` ${p.width}×${p.height}`) : null)));
    showVerdict(verdict, layer, flag('aligned'));
    showQuality(quality, q);
    reportBox.hidden = !flag('aligned');
    if (!reportBox.hidden) reportFrame.src = `${base}/report?v=${Date.now()}`;  // the report is rewritten after each run
  };

  // --- upload, one file at a time -------------------------------------------------
  const rowFor = (file) => {
    for (const li of uploads.children) if (li.dataset.name === file.name) return li;
    const li = el('li', {'data-name': file.name},
      el('span', {class: 'upload-name'}, file.name),
      el('progress', {max: 1, value: 0, 'aria-label': `upload of ${file.name}`}),
      el('span', {class: 'upload-status'}));
    uploads.appendChild(li);
    return li;
  };
  const setRow = (li, state, text, fraction) => {
    li.dataset.state = state;
    li.querySelector('.upload-status').textContent = text;
    if (fraction !== undefined) li.querySelector('progress').value = fraction;
  };

  uploadButton.addEventListener('click', async () => {
    const chosen = [...files.files];
    if (!chosen.length) {
      showMessage('Choose the photos to upload first.', 'error');
      files.focus();
      return;
    }
    uploadButton.disabled = true;
    showMessage(`Uploading ${chosen.length} photo${chosen.length === 1 ? '' : 's'}…`, 'info');
    const tally = {stored: 0, present: 0, failed: 0};
    try {
      try {
        await reload();  // the photos the server holds now, to skip them
      } catch { /* keep what is known; the server decides anyway */ }
      const rows = chosen.map((f) => {
        const li = rowFor(f);
        if (li.dataset.state !== 'stored' && li.dataset.state !== 'present') setRow(li, 'waiting', 'waiting', 0);
        return li;
      });
      for (const [i, file] of chosen.entries()) {
        if (signal.aborted) return;
        const li = rows[i];
        if (present.has(file.name)) {
          setRow(li, 'present', 'already present', 1);
          tally.present++;
          continue;
        }
        setRow(li, 'uploading', 'uploading…', 0);
        try {
          const r = await api.upload(`${base}/photos?name=${enc(file.name)}`, file,
                                     (loaded, total) => { li.querySelector('progress').value = loaded / total; });
          if (r && r.already_present) {
            setRow(li, 'present', 'already present', 1);
            tally.present++;
          } else {
            setRow(li, 'stored', 'stored', 1);
            tally.stored++;
          }
          present.add(file.name);
        } catch (err) {
          setRow(li, 'failed', err.message || String(err), 0);
          tally.failed++;
        }
      }
      const text = `${tally.stored} stored, ${tally.present} already present, ${tally.failed} failed.`;
      if (tally.failed) showMessage(`${text} Press Upload again to retry the failed ones.`, 'error');
      else showMessage(text, 'ok');
      await reload();
    } catch (err) {
      showError(err);
    } finally {
      uploadButton.disabled = false;
    }
  });

  // --- the processing job ---------------------------------------------------------
  const stopFollowing = () => stopJob();
  signal.addEventListener('abort', stopFollowing);

  const showState = (j) => {
    jobBox.classList.remove('idle');
    jobState.textContent = j.state;
    jobState.dataset.state = j.state;
    jobMessage.textContent = j.message || '';
    const running = ACTIVE.has(j.state);
    processButton.disabled = running;
    cancelButton.disabled = !running;
    if (j.stage) jobStage.textContent = j.stage;
    if (j.total > 0) showProgress({stage: j.stage, done: j.done, total: j.total});
  };

  const showProgress = (p) => {
    if (p.stage) jobStage.textContent = p.stage;
    if (p.total > 0) {
      jobProgress.max = p.total;
      jobProgress.value = Math.min(p.done || 0, p.total);
      jobPercent.textContent = percent(p.done || 0, p.total);
    } else {
      jobProgress.removeAttribute('value');  // indeterminate
      jobPercent.textContent = '';
    }
    if (p.elapsed_s !== undefined) jobElapsed.textContent = duration(p.elapsed_s);
  };

  const finish = async (j) => {
    stopFollowing();
    job = j;
    showState(j);
    if (j.state === 'done') {
      jobProgress.value = jobProgress.max;
      jobPercent.textContent = '100 %';
    }
    showMessage(...endMessage(`Processing of ${name}`, j, 'see the log'));
    try {
      await reload();
    } catch (err) {
      if (!signal.aborted) showError(err);
    }
  };

  const follow = (j) => {
    stopFollowing();
    job = j;
    showState(j);
    stopJob = followJob(j, {
      onProgress: (p) => {
        if (jobState.dataset.state === 'queued') showState({...job, state: 'running'});
        showProgress(p);
      },
      onLog: (l) => {
        jobLog.appendChild(el('li', {class: `level-${l.level || 'info'}`},
          el('span', {class: 'level'}, l.level || 'info'), ' ', l.message || ''));
        while (jobLog.children.length > LOG_LINES) jobLog.firstElementChild.remove();
        jobLog.scrollTop = jobLog.scrollHeight;
      },
      onEnd: finish,
    });
  };

  processForm.addEventListener('submit', async (event) => {
    event.preventDefault();
    processButton.disabled = true;
    try {
      const j = await api.post(`${base}/process`, {until: until.value || 'products'});
      replace(jobLog);
      jobStage.textContent = 'starting';
      jobElapsed.textContent = '';
      showProgress({done: 0, total: 0});
      showMessage(`Processing of ${name} started.`, 'info');
      follow(j);
    } catch (err) {
      processButton.disabled = Boolean(job && ACTIVE.has(job.state));
      showError(err, processForm);
    }
  });

  cancelButton.addEventListener('click', async () => {
    if (!job) return;
    cancelButton.disabled = true;
    try {
      await api.post(`/api/jobs/${enc(job.id)}/cancel`, {});
      showMessage('Asked the job to stop; its changes are rolled back.', 'info');
    } catch (err) {
      cancelButton.disabled = false;
      showError(err);
    }
  });

  // --- open -----------------------------------------------------------------------
  try {
    await reload();
  } catch (err) {
    if (signal.aborted) return;
    replace(summary, el('p', {class: 'muted'}, `The layer ${name} could not be read.`));
    showError(err);
    return;
  }
  try {
    const jobs = await api.get('/api/jobs');
    if (signal.aborted) return;
    const mine = (jobs || []).find((j) => j.layer === name);  // newest first
    if (mine && ACTIVE.has(mine.state)) follow(mine);
    else if (mine) showState(mine);
  } catch (err) {
    if (!signal.aborted) showError(err);
  }
}

function showVerdict(node, layer, aligned) {
  const v = layer.verdict;
  if (!aligned || !v) {
    node.className = 'verdict pending';
    node.dataset.ready = 'unknown';
    replace(node,
      el('h3', {id: 'verdict-headline'}, 'Not aligned yet'),
      el('p', {}, 'The layer has no alignment, so there is no verdict yet: upload its photos and press Process.'));
    return;
  }
  node.className = v.ready ? 'verdict ready' : 'verdict not-ready';
  node.dataset.ready = v.ready ? 'true' : 'false';
  const findings = Array.isArray(v.findings) ? v.findings : [];
  replace(node,
    el('h3', {id: 'verdict-headline'}, v.ready ? 'Ready to dig' : 'Not ready to dig'),
    findings.length
      ? el('ul', {id: 'findings', class: 'findings'}, findings.map((f) =>
          el('li', {class: `finding severity-${f.severity}`, 'data-severity': f.severity, 'data-rule': f.rule},
            el('p', {}, el('span', {class: 'badge'}, f.severity), ' ', el('span', {class: 'finding-message'}, f.message)),
            f.advice ? el('p', {class: 'advice'}, el('strong', {}, 'What to do: '), f.advice) : null)))
      : el('p', {id: 'findings', class: 'muted'}, 'No findings.'));
}

// The quality figures the server gives, scalars only, in the order given.
function showQuality(node, q) {
  const rows = Object.entries(q).filter(([, v]) => v === null || ['number', 'string', 'boolean'].includes(typeof v));
  if (!rows.length) {
    replace(node);
    return;
  }
  const show = (k, v) => {
    if (typeof v === 'number' && k.endsWith('_px')) return `${v.toFixed(2)} px`;
    if (typeof v === 'number' && k.endsWith('_m')) return `${coord(v)} m`;
    return figure(v);
  };
  replace(node, el('details', {class: 'quality'}, el('summary', {}, 'Quality figures'),
    el('dl', {id: 'quality-figures', class: 'facts'},
      rows.map(([k, v]) => el('div', {'data-key': k}, el('dt', {}, words(k)), el('dd', {}, show(k, v)))))));
}
