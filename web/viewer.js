// cslam live viewer, entry point: loads the viewer's modules (app.js and what it imports, all
// served from the web root by cslam-server) and says so in the page if they cannot be loaded,
// e.g. a server binary older than these files.
import('/app.js').catch((e) => {
  const msg = `viewer modules could not be loaded (${e.message}); the server must serve web/*.js`;
  document.getElementById('server').textContent = msg;
  const banner = document.getElementById('banner');
  banner.hidden = false;
  banner.className = 'lost';
  banner.textContent = msg;
});
