// The page's HTML side: client table, event timeline, dense-map summary, download menu, the
// full-rate reconstruction button and the connection banner.
import { api, token, downloadWithToken } from './net.js';
import { colour } from './scene.js';

export const $ = (id) => document.getElementById(id);
const hex = (c) => '#' + c.toString(16).padStart(6, '0');
const esc = (s) => String(s).replace(/[&<>"']/g, (ch) => `&#${ch.charCodeAt(0)};`);
const kb = (b) => (b >= 1e6 ? `${(b / 1e6).toFixed(1)} MB` : `${(b / 1e3).toFixed(1)} KB`);

// The client's link (status `link`, null when the server has no network layer): MB/s over the
// last 2 s and the compression ratio so far, with the share of light frames of a lean stream.
function linkCells(link) {
  if (!link) return '<td class="rate">–</td><td class="ratio">–</td>';
  const rate = link.bytes_per_s === null ? '–' : (link.bytes_per_s / 1e6).toFixed(2);
  return `<td class="rate">${rate}</td><td class="ratio" title="${link.frames_light} light frame(s)">${link.compression_ratio.toFixed(1)}×</td>`;
}

export function renderStatus(s) {
  $('server').textContent = `${s.server} ${s.version} · up ${s.uptime_s.toFixed(0)} s · ${s.clients.length} client(s) · ${s.fusion_events} event(s)`;
  $('clients').tBodies[0].innerHTML = s.clients.map((c) => `
    <tr data-client="${c.id}"><td><span class="swatch" style="background:${hex(colour(c.id))}"></span>${c.id}</td>
    <td>${esc(c.name)}</td><td class="connection">${esc(c.connection)}</td><td class="${esc(c.tracking)}">${esc(c.tracking)}</td>
    <td>${c.frames_received}</td><td>${c.frames_processed}</td><td>${c.frames_dropped}</td><td>${c.fps.toFixed(1)}</td>${linkCells(c.link)}
    <td>${c.keyframes}</td><td>${c.map_points}</td><td>${c.group}</td></tr>`).join('');
}

export function renderEvents(events, uptime) {
  const span = Math.max(uptime, ...events.map((e) => e.time_s), 1);
  $('timeline').innerHTML = events.map((e) =>
    `<div class="event ${esc(e.kind)}" style="left:${(98 * e.time_s / span).toFixed(2)}%" title="${esc(e.kind)} ${e.clients.join('+')} at ${e.time_s.toFixed(1)} s"></div>`).join('');
  $('events').innerHTML = events.length ? events.map((e) =>
    `${e.time_s.toFixed(1)} s: ${esc(e.kind)} of clients ${e.clients.join(' + ')} → group ${e.group}, ${e.inliers} inliers, ${e.duration_ms.toFixed(0)} ms`).join('<br>') : 'none yet';
}

// Whether the server's map shows everything it was given at the current poses (older servers: nothing).
function settledText(status) {
  if (status.settled === undefined) return '';
  if (status.settled) return ', settled';
  return `, catching up (${status.queue + status.pending} keyframes waiting, ${status.stale_meshes} meshes stale, ` +
    `${status.distorted_submaps} submaps to re-integrate)`;
}

export function renderDenseInfo(status, st, traffic) {
  if (status && status.enabled === false) { $('dense-info').textContent = 'the server runs without a dense map'; return; }
  if (status === null) { $('dense-info').textContent = 'this server has no dense-map routes'; return; }
  const groups = Object.entries(st.groups).map(([g, v]) =>
    `group ${g}: ${v.submaps.length} submaps, ${(v.triangles / 1e3).toFixed(0)}k triangles${v.missing ? `, <b>${v.missing} missing</b>` : ''}`);
  const srv = status ? `server: ${status.submaps} submaps, ${status.keyframes_integrated} keyframes integrated, queue ${status.queue}` +
    (status.integrate_ms ? `, ${status.integrate_ms.p50.toFixed(1)} ms/keyframe` : '') + settledText(status) : '';
  $('dense-info').innerHTML = [srv, ...groups,
    `downloaded ${kb(traffic.total)} (${kb(traffic.perMinute())} in the last minute; meshes ${st.meshLoaded}/${st.meshDownloads}, ` +
    `${st.poseOnlyUpdates} pose-only updates, ${st.inFlight} loading)`,
    st.errors ? `<span class="lost">${st.errors} load error(s); last: ${esc(st.lastErrors.at(-1)?.message || '')}</span>` : ''].filter(Boolean).join('<br>');
}

// Connection banner: red while lost, green for a few seconds once back.
let bannerTimer = null;
export function showConnection(ok, text) {
  const b = $('banner');
  clearTimeout(bannerTimer);
  b.hidden = false;
  b.className = ok ? 'back' : 'lost';
  b.textContent = text;
  if (ok) bannerTimer = setTimeout(() => { b.hidden = true; }, 4000);
}

// Download menu: each link fetches its route for the chosen group (with the token) and saves it.
export function setupDownloads(groupForDownload) {
  for (const a of document.querySelectorAll('#downloads a[data-route]')) {
    a.addEventListener('click', async (e) => {
      e.preventDefault();
      const G = groupForDownload();
      if (G === null) { $('download-msg').textContent = 'no group yet'; return; }
      const route = a.dataset.route, url = `/api/dense/${route}?group=${G}`;
      $('download-msg').textContent = `downloading ${route} of group ${G}…`;
      try {
        await downloadWithToken(url, `group${G}_${route}`);
        $('download-msg').textContent = `${route} of group ${G} saved`;
      } catch (err) {
        $('download-msg').textContent = `${route}: ${err.message}`;
      }
    });
  }
}

// The one-shot full-rate reconstruction (POST /api/reconstruction) with its PLY links.
export function setupReconstruction() {
  $('recon-start').addEventListener('click', async () => {
    $('recon-start').disabled = true;
    $('recon-links').hidden = true;
    try {
      const { job } = await (await api('/api/reconstruction', { method: 'POST' })).json();
      for (;;) {
        const s = await (await api(`/api/reconstruction/${job}`)).json();
        $('recon-state').textContent = `job ${job}: ${s.state} ${(100 * s.progress).toFixed(0)}% ${s.message}`;
        if (s.state === 'done') {
          $('dl-cloud').href = s.cloud_url;
          $('dl-mesh').href = s.mesh_url || '';
          $('dl-mesh').hidden = !s.mesh_url;
          $('recon-links').hidden = false;
          break;
        }
        if (s.state !== 'running' && s.state !== 'queued') break;
        await new Promise((r) => setTimeout(r, 500));
      }
    } catch (e) {
      $('recon-state').textContent = String(e.message);
    }
    $('recon-start').disabled = false;
  });
  // With a token the links cannot carry the header: download through fetch.
  for (const id of ['dl-cloud', 'dl-mesh']) {
    $(id).addEventListener('click', async (e) => {
      if (!token) return;
      e.preventDefault();
      await downloadWithToken($(id).getAttribute('href'), $(id).textContent);
    });
  }
}
