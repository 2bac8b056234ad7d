// Following a job of the server (docs/api.md, "Jobs and their events"): its Server-Sent
// Events as they come, closed on the end event (else the browser reconnects and the
// stream starts again), and when the stream cannot be had (a proxy, a restart) the job
// read every two seconds instead. The one place the pages follow a job.
import {api, enc} from './api.js';

export const ACTIVE = new Set(['queued', 'running']);
const POLL_MS = 2000;

const parse = (e) => {
  try {
    return JSON.parse(e.data);
  } catch {
    return null;
  }
};

// What to tell the user of a job that ended: [text, kind] for showMessage. `what` names
// the work ("Processing of L1"); `failedHint` says where to look when it failed.
export function endMessage(what, j, failedHint) {
  if (j.state === 'done') return [`${what} finished${j.message ? `: ${j.message}` : '.'}`, 'ok'];
  if (j.state === 'failed') return [`${what} failed: ${j.message || failedHint}`, 'error'];
  if (j.state === 'cancelled') return [`${what} was cancelled; the project is as it was before.`, 'info'];
  return [`${what}: ${j.state}`, 'info'];
}

// Follows job `job` (as the API gives it). handlers: onProgress(p) for each progress
// event ({stage, done, total, elapsed_s}), onLog(l) for each log line ({level,
// message}), onEnd(job) once, with the job as it ended. Returns stop(), which ends
// the following without touching the job (a closed page does not stop a job).
export function followJob(job, {onProgress = () => {}, onLog = () => {}, onEnd = () => {}} = {}) {
  let events = null;
  let poll = 0;
  let stopped = false;
  const stop = () => {
    stopped = true;
    if (events) events.close();
    events = null;
    clearTimeout(poll);
  };
  const end = (j) => {
    if (stopped) return;
    stop();
    onEnd(j);
  };
  const pollJob = () => {
    clearTimeout(poll);
    poll = setTimeout(async () => {
      if (stopped) return;
      try {
        const j = await api.get(`/api/jobs/${enc(job.id)}`);
        if (ACTIVE.has(j.state)) {
          onProgress(j);
          pollJob();
        } else {
          end(j);
        }
      } catch {
        pollJob();
      }
    }, POLL_MS);
  };
  const es = new EventSource(`/api/jobs/${enc(job.id)}/events`);
  events = es;
  es.addEventListener('progress', (e) => {
    const p = parse(e);
    if (p && !stopped) onProgress(p);
  });
  es.addEventListener('log', (e) => {
    const l = parse(e);
    if (l && !stopped) onLog(l);
  });
  es.addEventListener('end', (e) => end(parse(e) || {...job, state: 'done'}));
  es.addEventListener('error', () => {
    if (es.readyState === EventSource.CLOSED && events === es && !stopped) {
      events = null;
      pollJob();
    }
  });
  return stop;
}
