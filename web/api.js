// The one place the pages talk to the server (docs/api.yaml). Every write carries
// the session's CSRF token; every refusal becomes an ApiError that showError turns
// into a message and, when it names a field, a marked form input.

export class ApiError extends Error {
  constructor(message, {status = 0, field = '', value = ''} = {}) {
    super(message);
    this.name = 'ApiError';
    this.status = status;
    this.field = field;
    this.value = value;
  }
}

let session = null;  // Promise of {user, role, csrf_token}

function getSession(fresh = false) {
  if (!session || fresh) {
    session = request('GET', '/api/session').catch((err) => {
      session = null;
      throw err;
    });
  }
  return session;
}

async function errorFrom(status, statusText, text) {
  let body = null;
  try {
    body = JSON.parse(text);
  } catch {
    body = null;
  }
  const e = body && body.error;
  if (e && e.message) return new ApiError(e.message, {status, field: e.field || '', value: e.value ?? ''});
  if (status === 413) return new ApiError('The file is larger than the server accepts.', {status});
  return new ApiError(`The server answered ${status} ${statusText || ''}`.trim(), {status});
}

async function request(method, path, body, token) {
  const headers = {Accept: 'application/json'};
  if (body !== undefined) headers['Content-Type'] = 'application/json';
  if (token) headers['X-CSRF-Token'] = token;
  let response;
  try {
    response = await fetch(path, {method, headers, body: body === undefined ? undefined : JSON.stringify(body),
                                  credentials: 'same-origin'});
  } catch {
    throw new ApiError('The server cannot be reached: is `strata serve` running, and the connection up?');
  }
  const text = await response.text();
  if (!response.ok) throw await errorFrom(response.status, response.statusText, text);
  if (!text) return null;
  try {
    return JSON.parse(text);
  } catch {
    return text;
  }
}

// A POST whose answer is not JSON (a drawing): the body as a Blob. Refusals are JSON
// and become ApiErrors as for every request.
async function requestBlob(path, body, token) {
  let response;
  try {
    response = await fetch(path, {method: 'POST', credentials: 'same-origin', body: JSON.stringify(body),
                                  headers: {'Content-Type': 'application/json', 'X-CSRF-Token': token}});
  } catch {
    throw new ApiError('The server cannot be reached: is `strata serve` running, and the connection up?');
  }
  if (!response.ok) throw await errorFrom(response.status, response.statusText, await response.text());
  return response.blob();
}

// A write; a 403 may mean the token went stale (the server restarted): fetch a
// fresh session once and try again.
async function write(send) {
  const {csrf_token: token} = await getSession();
  try {
    return await send(token);
  } catch (err) {
    if (err instanceof ApiError && err.status === 403) {
      const fresh = await getSession(true);
      if (fresh.csrf_token !== token) return send(fresh.csrf_token);
    }
    throw err;
  }
}

function uploadOnce(path, file, onProgress, token) {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open('POST', path);
    xhr.setRequestHeader('Content-Type', 'application/octet-stream');
    xhr.setRequestHeader('Accept', 'application/json');
    if (token) xhr.setRequestHeader('X-CSRF-Token', token);
    xhr.upload.onprogress = (e) => {
      if (onProgress && e.lengthComputable) onProgress(e.loaded, e.total);
    };
    xhr.onload = async () => {
      if (xhr.status >= 200 && xhr.status < 300) {
        try {
          resolve(xhr.responseText ? JSON.parse(xhr.responseText) : null);
        } catch {
          resolve(null);
        }
      } else {
        reject(await errorFrom(xhr.status, xhr.statusText, xhr.responseText));
      }
    };
    xhr.onerror = () => reject(new ApiError('The upload was interrupted (connection lost?): press Upload again to resume.'));
    xhr.onabort = () => reject(new ApiError('The upload was stopped.'));
    xhr.send(file);
  });
}

export const api = {
  get: (path) => request('GET', path),
  post: (path, body = {}) => write((token) => request('POST', path, body, token)),
  postForBlob: (path, body = {}) => write((token) => requestBlob(path, body, token)),
  upload: (path, file, onProgress) => write((token) => uploadOnce(path, file, onProgress, token)),
  session: () => getSession(),
};

// Path segments of the API, always encoded.
export const enc = encodeURIComponent;

// --- messages -----------------------------------------------------------------------

function bar() {
  return document.getElementById('message');
}

export function showMessage(text, kind = 'info') {
  const m = bar();
  if (!m) return;
  m.textContent = text;
  m.className = text ? kind : '';
  m.dataset.kind = kind;
}

export function clearMessage() {
  showMessage('');
  clearInvalid(document);
}

export function clearInvalid(scope) {
  for (const input of scope.querySelectorAll('[aria-invalid="true"]')) input.removeAttribute('aria-invalid');
}

// The one way an error reaches the user: its message in #message; when it names a
// field that an input of `scope` (a form, else the page) carries as its name, that
// input is marked and focused.
export function showError(err, scope) {
  const message = (err && err.message) || String(err);
  showMessage(message, 'error');
  if (!err || !err.field) return;
  const root = scope || document.getElementById('page') || document;
  const input = root.querySelector(`[name="${CSS.escape(err.field)}"]`);
  if (!input) return;
  input.setAttribute('aria-invalid', 'true');
  input.setAttribute('aria-describedby', 'message');
  input.addEventListener('input', () => input.removeAttribute('aria-invalid'), {once: true});
  input.addEventListener('change', () => input.removeAttribute('aria-invalid'), {once: true});
  input.focus();
}

// --- forms ----------------------------------------------------------------------------

// The form's named controls as an API body: number inputs as numbers, empty optional
// values left out.
export function formBody(form) {
  const body = {};
  for (const c of form.elements) {
    if (!c.name || c.disabled) continue;
    const raw = c.value.trim();
    if (raw === '') continue;
    body[c.name] = c.type === 'number' ? Number(raw) : raw;
  }
  return body;
}

// Submit (button or Enter) -> submit(body, form); the button is held while it runs
// and any refusal goes through showError with the form as scope.
export function onSubmit(form, submit) {
  form.addEventListener('submit', async (event) => {
    event.preventDefault();
    clearInvalid(form);
    const buttons = form.querySelectorAll('button');
    for (const b of buttons) b.disabled = true;
    form.setAttribute('aria-busy', 'true');
    try {
      await submit(formBody(form), form);
    } catch (err) {
      showError(err, form);
    } finally {
      for (const b of buttons) b.disabled = false;
      form.removeAttribute('aria-busy');
    }
  });
}
