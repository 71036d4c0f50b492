// The 2D occupancy grid of a group (/api/dense/occupancy.json) as a textured plane under
// T_world_grid: free cells light, occupied dark, unknown transparent. Row 0 of the data is grid y = 0
// (bottom), which is texture row 0 (v = 0) of a PlaneGeometry.

export const MAX_GRID_CELLS = 4096 * 4096;

export function decodeGrid(json) {
  const { width: W, height: H, resolution: r, T_world_grid: T } = json;
  if (!(Number.isInteger(W) && Number.isInteger(H) && W > 0 && H > 0 && W * H <= MAX_GRID_CELLS))
    throw new Error(`occupancy: bad size ${W} x ${H}`);
  if (!(r > 0) || !Array.isArray(T) || T.length !== 7 || !T.every(Number.isFinite)) throw new Error('occupancy: bad resolution or pose');
  const bin = atob(json.data || '');
  if (bin.length !== W * H) throw new Error(`occupancy: ${bin.length} cells, expected ${W * H}`);
  const rgba = new Uint8Array(4 * W * H);
  for (let i = 0; i < W * H; i++) {
    const v = (bin.charCodeAt(i) << 24) >> 24;  // int8
    if (v < 0) continue;  // unknown: transparent
    const shade = v >= 50 ? 30 : 235 - Math.round(1.5 * v);
    rgba.set([shade, shade, v >= 50 ? 40 : shade, v >= 50 ? 230 : 110], 4 * i);
  }
  return { W, H, r, T, rgba };
}

export class OccupancyLayer {
  constructor(view, api) {
    Object.assign(this, { view, api, THREE: view.THREE, layer: view.layers.occupancy });
    this.byGroup = new Map();  // group -> {obj, etag}
    this.errors = 0;
    this.lastError = '';
  }

  async poll(groups) {
    for (const G of groups) {
      const cur = this.byGroup.get(G);
      try {
        const res = await this.api(`/api/dense/occupancy.json?group=${G}`, { etag: cur?.etag });
        if (res.status === 304) continue;
        const grid = decodeGrid(await res.json());
        this.set(G, grid, res.headers.get('ETag'));
      } catch (e) {
        if (e.status === 404) { this.drop(G); continue; }  // no grid yet
        this.errors += 1;
        this.lastError = String(e.message);
      }
    }
    for (const G of [...this.byGroup.keys()]) if (!groups.includes(G)) this.drop(G);
  }

  set(G, { W, H, r, T, rgba }, etag) {
    const THREE = this.THREE;
    this.drop(G);
    const tex = new THREE.DataTexture(rgba, W, H, THREE.RGBAFormat);
    tex.magFilter = THREE.NearestFilter;
    tex.needsUpdate = true;
    const plane = new THREE.Mesh(new THREE.PlaneGeometry(W * r, H * r),
      new THREE.MeshBasicMaterial({ map: tex, transparent: true, side: THREE.DoubleSide, depthWrite: false }));
    plane.position.set(W * r / 2, H * r / 2, 0);
    const obj = new THREE.Group();
    obj.name = `occupancy-${G}`;
    obj.position.set(T[0], T[1], T[2]);
    obj.quaternion.set(T[3], T[4], T[5], T[6]).normalize();
    obj.add(plane);
    obj.userData = { group: G, width: W, height: H, resolution: r };
    this.layer.add(obj);
    this.byGroup.set(G, { obj, etag });
    this.view.invalidate();
  }

  drop(G) {
    const cur = this.byGroup.get(G);
    if (!cur) return;
    cur.obj.traverse((o) => { o.geometry?.dispose(); o.material?.map?.dispose(); o.material?.dispose(); });
    cur.obj.removeFromParent();
    this.byGroup.delete(G);
    this.view.invalidate();
  }

  setVisibleGroup(G) {
    for (const [g, { obj }] of this.byGroup) obj.visible = G === null || g === G;
    this.view.invalidate();
  }

  state() {
    return { groups: [...this.byGroup.values()].map(({ obj }) => obj.userData), errors: this.errors, lastError: this.lastError };
  }
}
