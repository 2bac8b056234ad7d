// The photo canvas of the markers workspace (markers.js): one photo at any zoom, the
// marks of one marker drawn over it and a loupe under the pointer. The wheel zooms
// around the cursor, two fingers pinch, dragging pans; a press that does not move (a
// click, a tap) places the marker; on touch a press held still aims: the loupe shows
// above the finger, the finger moves the aim and lifting it places.
//
// All geometry is in CSS pixels: the photo is drawn with its top-left corner at (ox, oy)
// of the canvas and `scale` CSS px per image pixel; the backing store follows
// devicePixelRatio for sharpness only, so a placed point depends neither on the zoom nor
// on the screen. Image points are full-image pixels, the centre of the top-left pixel
// being (0, 0): canvas point (u, v) is image point ((u - ox) / scale - 0.5, (v - oy) /
// scale - 0.5), whatever the size of the file drawn (a thumbnail while the photo loads).
import {el} from './dom.js';

const DRAG_PX = 4;        // a press that moves further is a pan, not a click
const AIM_MS = 350;       // a touch held still this long aims with the loupe
const LOUPE_PX = 160;     // the loupe's side, CSS px
const LOUPE_ZOOM = 4;     // the loupe magnifies the view this much,
const LOUPE_MIN = 8;      // an image pixel to at least this many CSS px,
const LOUPE_MAX = 48;     // and to at most this many (more shows too few pixels to aim)
const MAX_SCALE = 64;     // CSS px per image pixel
const BACKDROP = '#2b2f31';
export const COLOURS = {clicked: '#1e8e3e', confirmed: '#146c2e', predicted: '#1f6fd1', detected: '#8e44c9',
                        rejected: '#d32f2f', none: '#80868b', survey: '#4a4f53'};

export function photoCanvas({onPlace, onError} = {}) {
  const canvas = el('canvas', {id: 'photo-canvas', role: 'img',
                               'aria-label': 'The photo: click or tap to place the marker, drag to pan, wheel or pinch to zoom'});
  const loupe = el('canvas', {id: 'loupe', class: 'loupe', 'aria-hidden': 'true', hidden: true});
  const node = el('div', {id: 'photo-view', class: 'photo-view', 'data-state': 'empty'}, canvas, loupe);
  const ctx = canvas.getContext('2d');
  const lctx = loupe.getContext('2d');

  let photo = null;           // {key, url, width, height, placeholder, label}
  let source = null;          // the image drawn: the photo, or its thumbnail while it loads
  let sharp = false;          // source is the photo itself (its pixels drawn square when enlarged)
  let W = 0;                  // the photo's full size, image px
  let H = 0;
  let ox = 0;
  let oy = 0;
  let scale = 1;
  let fitted = true;          // the view is "fit": a resize fits again
  let cw = 0;                 // the canvas's size, CSS px
  let ch = 0;
  let entry = null;           // the marker's entry for this photo (markers.js), drawn over it
  let label = '';             // the marker's name
  let pending = null;         // [x, y] placed, waiting for the server
  let frame = 0;
  let dirty = true;           // the photo must be drawn again (else only the loupe moved)
  let lens = null;            // {u, v, touch}: where the loupe looks, canvas CSS px

  // --- geometry -------------------------------------------------------------------
  const fitScale = () => (W && H && cw && ch ? Math.min(cw / W, ch / H) : 1);
  const clampScale = (s) => Math.min(MAX_SCALE, Math.max(fitScale() / 4, s));
  const toImage = (u, v) => [(u - ox) / scale - 0.5, (v - oy) / scale - 0.5];
  const inside = (x, y) => x >= -0.5 && y >= -0.5 && x <= W - 0.5 && y <= H - 0.5;
  const schedule = (photoToo = true) => {
    dirty = dirty || photoToo;
    if (!frame) frame = requestAnimationFrame(draw);
  };

  const fit = () => {
    fitted = true;
    if (!W || !cw) return;
    scale = fitScale();
    ox = (cw - W * scale) / 2;
    oy = (ch - H * scale) / 2;
    schedule();
  };

  // Zoom by f keeping the image point under canvas point (u, v) where it is.
  const zoomAt = (u, v, f) => {
    if (!W) return;
    const s = clampScale(scale * f);
    ox = u - ((u - ox) * s) / scale;
    oy = v - ((v - oy) * s) / scale;
    scale = s;
    fitted = false;
    schedule();
  };

  const centreOn = (x, y, s = scale) => {
    scale = clampScale(s);
    ox = cw / 2 - (x + 0.5) * scale;
    oy = ch / 2 - (y + 0.5) * scale;
    fitted = false;
    schedule();
  };

  const backing = () => {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(cw * dpr));
    const h = Math.max(1, Math.round(ch * dpr));
    if (canvas.width === w && canvas.height === h) return false;
    canvas.width = w;  // clears it
    canvas.height = h;
    return true;
  };

  const measure = () => {
    const r = canvas.getBoundingClientRect();
    if (!r.width || !r.height) return;
    const first = !cw;
    const cx = (cw / 2 - ox) / scale;  // the image point at the centre, kept there
    const cy = (ch / 2 - oy) / scale;
    cw = r.width;
    ch = r.height;
    backing();
    if (first || fitted) fit();
    else {
      ox = cw / 2 - cx * scale;
      oy = ch / 2 - cy * scale;
    }
    dirty = true;
    draw();  // now: resizing the backing store cleared it
  };
  const resizer = new ResizeObserver(measure);
  resizer.observe(canvas);

  // --- drawing --------------------------------------------------------------------
  // The part of the source visible in a w x h box, whole source pixels only, with the
  // photo's top-left corner at (x0, y0) and s box px per image px.
  const paint = (c, x0, y0, s, w, h) => {
    const nw = source.naturalWidth || W;
    const nh = source.naturalHeight || H;
    const kx = nw / W;  // source px per image px (1 for the photo itself)
    const ky = nh / H;
    const a = Math.max(0, Math.floor((-x0 / s) * kx));
    const b = Math.min(nw, Math.ceil(((w - x0) / s) * kx));
    const t = Math.max(0, Math.floor((-y0 / s) * ky));
    const d = Math.min(nh, Math.ceil(((h - y0) / s) * ky));
    if (b <= a || d <= t) return;
    c.imageSmoothingEnabled = !sharp || s / kx < 2;
    c.imageSmoothingQuality = 'high';
    c.drawImage(source, a, t, b - a, d - t, x0 + (a / kx) * s, y0 + (t / ky) * s, ((b - a) / kx) * s, ((d - t) / ky) * s);
  };

  const stroke = (c, colour, width, path) => {
    c.beginPath();
    path();
    c.lineWidth = width + 2.5;
    c.strokeStyle = 'rgba(255,255,255,0.9)';
    c.stroke();
    c.lineWidth = width;
    c.strokeStyle = colour;
    c.stroke();
  };
  const ring = (c, x, y, r) => () => c.arc(x, y, r, 0, 2 * Math.PI);
  const dot = (c, x, y, r, colour) => {
    c.beginPath();
    c.arc(x, y, r + 1.25, 0, 2 * Math.PI);
    c.fillStyle = 'rgba(255,255,255,0.9)';
    c.fill();
    c.beginPath();
    c.arc(x, y, r, 0, 2 * Math.PI);
    c.fillStyle = colour;
    c.fill();
  };

  // The survey's prediction: a grey crosshair open at its centre.
  const cross = (c, x, y) => stroke(c, COLOURS.survey, 1.5, () => {
    for (const [dx, dy] of [[1, 0], [-1, 0], [0, 1], [0, -1]]) {
      c.moveTo(x + 4 * dx, y + 4 * dy);
      c.lineTo(x + 15 * dx, y + 15 * dy);
    }
  });

  const symbol = (c, status, x, y) => {
    const colour = COLOURS[status] || COLOURS.none;
    if (status === 'rejected') {
      stroke(c, colour, 2.5, () => {
        c.moveTo(x - 7, y - 7); c.lineTo(x + 7, y + 7);
        c.moveTo(x + 7, y - 7); c.lineTo(x - 7, y + 7);
      });
    } else if (status === 'detected') {
      stroke(c, colour, 2, () => c.rect(x - 8, y - 8, 16, 16));
      dot(c, x, y, 1.5, colour);
    } else if (status === 'predicted') {
      stroke(c, colour, 2, ring(c, x, y, 10));
      dot(c, x, y, 1.25, colour);
    } else {  // clicked, confirmed (and an observation of unknown status)
      stroke(c, colour, 2, ring(c, x, y, 10));
      dot(c, x, y, 2.5, colour);
      if (status === 'confirmed') {
        stroke(c, colour, 2.5, () => {
          c.moveTo(x + 9, y - 13); c.lineTo(x + 12.5, y - 9.5); c.lineTo(x + 19, y - 18);
        });
      }
    }
  };

  const text = (c, s, x, y, colour) => {
    c.font = '600 12px system-ui, sans-serif';
    c.textBaseline = 'middle';
    c.lineJoin = 'round';
    c.lineWidth = 3.5;
    c.strokeStyle = 'rgba(255,255,255,0.95)';
    c.strokeText(s, x, y);
    c.fillStyle = colour;
    c.fillText(s, x, y);
  };

  // The marks of the entry, `at` mapping an image point to the box's px.
  const marks = (c, at) => {
    if (entry && Array.isArray(entry.predicted)) cross(c, ...at(entry.predicted[0], entry.predicted[1]));
    const o = entry && entry.observation;
    if (o && Number.isFinite(o.x) && Number.isFinite(o.y)) {
      const [x, y] = at(o.x, o.y);
      const status = entry.status && entry.status !== 'none' ? entry.status : 'clicked';
      symbol(c, status, x, y);
      const r = Number.isFinite(entry.residual_px) ? `  ${entry.residual_px.toFixed(2)} px` : '';
      text(c, `${label}${r}`, x + 15, y + 12, COLOURS[status] || COLOURS.none);
    }
    if (pending) {
      const [x, y] = at(pending[0], pending[1]);
      stroke(c, COLOURS.clicked, 1.5, ring(c, x, y, 10));
      dot(c, x, y, 2, COLOURS.clicked);
    }
  };

  const draw = () => {
    cancelAnimationFrame(frame);
    frame = 0;
    if (!cw) return;
    if (backing()) dirty = true;  // devicePixelRatio changed (another screen, the browser's zoom)
    if (dirty) {
      dirty = false;
      ctx.setTransform(canvas.width / cw, 0, 0, canvas.height / ch, 0, 0);
      ctx.fillStyle = BACKDROP;
      ctx.fillRect(0, 0, cw, ch);
      if (source && W) {
        paint(ctx, ox, oy, scale, cw, ch);
        marks(ctx, (x, y) => [ox + (x + 0.5) * scale, oy + (y + 0.5) * scale]);
      }
    }
    drawLoupe();
  };

  const drawLoupe = () => {
    const [x, y] = lens ? toImage(lens.u, lens.v) : [0, 0];
    if (!lens || !source || !W || !inside(x, y)) {
      loupe.hidden = true;
      return;
    }
    loupe.hidden = false;
    const L = LOUPE_PX;
    const dpr = window.devicePixelRatio || 1;
    if (loupe.width !== Math.round(L * dpr)) {
      loupe.width = Math.round(L * dpr);
      loupe.height = Math.round(L * dpr);
    }
    const s = Math.max(LOUPE_MIN, Math.min(scale * LOUPE_ZOOM, Math.max(LOUPE_MAX, scale)));
    const lx = L / 2 - (x + 0.5) * s;
    const ly = L / 2 - (y + 0.5) * s;
    lctx.setTransform(loupe.width / L, 0, 0, loupe.height / L, 0, 0);
    lctx.fillStyle = BACKDROP;
    lctx.fillRect(0, 0, L, L);
    paint(lctx, lx, ly, s, L, L);
    marks(lctx, (a, b) => [lx + (a + 0.5) * s, ly + (b + 0.5) * s]);
    stroke(lctx, '#e53935', 1, () => {  // the crosshair, open where the point is
      lctx.moveTo(L / 2, 0); lctx.lineTo(L / 2, L / 2 - 5);
      lctx.moveTo(L / 2, L / 2 + 5); lctx.lineTo(L / 2, L);
      lctx.moveTo(0, L / 2); lctx.lineTo(L / 2 - 5, L / 2);
      lctx.moveTo(L / 2 + 5, L / 2); lctx.lineTo(L, L / 2);
    });
    text(lctx, `${x.toFixed(1)}, ${y.toFixed(1)}`, 6, L - 10, '#1d2327');
    // Beside the mouse; above the finger (below it when there is no room above).
    let left = lens.touch ? lens.u - L / 2 : lens.u + 24;
    let top = lens.touch ? lens.v - L - 56 : lens.v + 24;
    if (lens.touch && top < 0) top = lens.v + 56;
    if (!lens.touch && left + L > cw) left = lens.u - 24 - L;
    if (!lens.touch && top + L > ch) top = lens.v - 24 - L;
    loupe.style.left = `${Math.max(0, Math.min(cw - L, left))}px`;
    loupe.style.top = `${Math.max(0, Math.min(ch - L, top))}px`;
  };

  // --- pointers: pan, pinch, click, aim -------------------------------------------
  const pointers = new Map();  // pointerId -> [u, v]
  let gesture = null;          // {kind: press | aim | pan | pinch | spent, start, last, touch, timer, dist, mid}
  const at = (e) => {
    const r = canvas.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  };
  const two = () => {
    const [a, b] = [...pointers.values()];
    return {dist: Math.hypot(a[0] - b[0], a[1] - b[1]) || 1, mid: [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2]};
  };

  canvas.addEventListener('pointerdown', (e) => {
    if (e.pointerType === 'mouse' && e.button !== 0) return;
    e.preventDefault();
    try {
      canvas.setPointerCapture(e.pointerId);
    } catch { /* a synthetic event: nothing to capture */ }
    const p = at(e);
    pointers.set(e.pointerId, p);
    if (gesture) clearTimeout(gesture.timer);
    if (pointers.size === 1) {
      const touch = e.pointerType === 'touch';
      gesture = {kind: 'press', start: p, last: p, touch, timer: 0};
      if (touch) {
        gesture.timer = setTimeout(() => {
          if (gesture && gesture.kind === 'press') {
            gesture.kind = 'aim';
            lens = {u: gesture.last[0], v: gesture.last[1], touch: true};
            schedule();
          }
        }, AIM_MS);
      } else {
        lens = {u: p[0], v: p[1], touch: false};
      }
    } else {
      gesture = {kind: 'pinch', ...two()};
      lens = null;
    }
    schedule();
  });

  canvas.addEventListener('pointermove', (e) => {
    const p = at(e);
    if (!pointers.has(e.pointerId)) {  // hovering: the loupe follows the mouse
      if (e.pointerType !== 'touch') {
        lens = {u: p[0], v: p[1], touch: false};
        schedule(false);
      }
      return;
    }
    pointers.set(e.pointerId, p);
    const g = gesture;
    if (!g) return;
    if (g.kind === 'press' && Math.hypot(p[0] - g.start[0], p[1] - g.start[1]) > DRAG_PX) {
      clearTimeout(g.timer);
      g.kind = 'pan';
      lens = null;
    }
    if (g.kind === 'pan') {
      ox += p[0] - g.last[0];
      oy += p[1] - g.last[1];
      fitted = false;
    } else if (g.kind === 'aim' || (g.kind === 'press' && !g.touch)) {
      lens = {u: p[0], v: p[1], touch: g.touch};
    } else if (g.kind === 'pinch' && pointers.size >= 2 && W) {
      const {dist, mid} = two();
      const s = clampScale((scale * dist) / g.dist);
      ox = mid[0] - ((g.mid[0] - ox) * s) / scale;  // the point under the fingers stays under them
      oy = mid[1] - ((g.mid[1] - oy) * s) / scale;
      scale = s;
      g.dist = dist;
      g.mid = mid;
      fitted = false;
    }
    g.last = p;
    schedule(g.kind === 'pan' || g.kind === 'pinch');
  });

  const release = (e, cancelled) => {
    if (!pointers.has(e.pointerId)) return;
    const p = at(e);
    pointers.delete(e.pointerId);
    const g = gesture;
    if (g) clearTimeout(g.timer);
    if (!cancelled && g && (g.kind === 'press' || g.kind === 'aim')) place(p);
    if (!pointers.size) {
      gesture = null;
      if (e.pointerType === 'touch') lens = null;
    } else if (g) {
      g.kind = 'spent';  // a finger left of a pinch neither pans nor places
    }
    schedule();
  };
  canvas.addEventListener('pointerup', (e) => release(e, false));
  canvas.addEventListener('pointercancel', (e) => release(e, true));
  canvas.addEventListener('pointerleave', () => {
    if (!pointers.size) {
      lens = null;
      schedule(false);
    }
  });
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());  // a long press aims

  canvas.addEventListener('wheel', (e) => {
    if (!W) return;
    e.preventDefault();
    const unit = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? ch : 1;
    const f = Math.min(2, Math.max(0.5, Math.exp(-e.deltaY * unit * 0.002)));
    const [u, v] = at(e);
    zoomAt(u, v, f);
    lens = {u, v, touch: false};
  }, {passive: false});

  const place = ([u, v]) => {
    if (!photo || !W || !source) return;
    const [x, y] = toImage(u, v);
    if (!inside(x, y)) return;
    pending = [x, y];
    schedule();
    if (onPlace) onPlace(x, y);
  };

  // --- the photo and its marks ----------------------------------------------------
  // Shows p ({key, url, width, height, placeholder: a loaded <img> of the same photo,
  // label}); returns whether it changed. The caller then fits or centres the view.
  const setPhoto = (p) => {
    if ((p && photo && p.key === photo.key) || (!p && !photo)) return false;
    photo = p;
    pending = null;
    source = null;
    sharp = false;
    W = p ? p.width || 0 : 0;
    H = p ? p.height || 0 : 0;
    node.dataset.state = p ? 'loading' : 'empty';
    if (!p) {
      schedule();
      return true;
    }
    const thumb = p.placeholder;
    if (W && H && thumb && thumb.complete && thumb.naturalWidth) source = thumb;
    const img = new Image();
    img.decoding = 'async';
    img.addEventListener('load', () => {
      if (photo !== p) return;
      if (!W || !H) {
        W = img.naturalWidth;
        H = img.naturalHeight;
        fit();
      }
      source = img;
      sharp = true;
      node.dataset.state = 'ready';
      schedule();
    });
    img.addEventListener('error', () => {
      if (photo !== p) return;
      node.dataset.state = 'error';
      if (onError) onError(new Error(`The photo ${p.label || p.key} could not be loaded from the server.`));
    });
    img.src = p.url;
    schedule();
    return true;
  };

  const setMarks = (e, name) => {
    entry = e || null;
    label = name || '';
    pending = null;
    schedule();
  };

  return {
    node,
    setPhoto,
    setMarks,
    fit,
    centreOn,
    zoomBy: (f) => zoomAt(cw / 2, ch / 2, f),
    clearPending: () => {
      pending = null;
      schedule();
    },
    isFitted: () => fitted,
    view: () => ({ox, oy, scale}),
    imageToClient: (x, y) => {
      const r = canvas.getBoundingClientRect();
      return {x: r.left + ox + (x + 0.5) * scale, y: r.top + oy + (y + 0.5) * scale};
    },
    clientToImage: (cx, cy) => {
      const r = canvas.getBoundingClientRect();
      const [x, y] = toImage(cx - r.left, cy - r.top);
      return {x, y};
    },
    destroy: () => {
      resizer.disconnect();
      cancelAnimationFrame(frame);
      if (gesture) clearTimeout(gesture.timer);
    },
  };
}
