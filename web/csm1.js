// CSM1: the server's per-submap mesh (docs: /api/dense/submaps/{id}/mesh.bin), little-endian:
//   "CSM1", uint32 geometry version, uint32 vertex count NV, uint32 triangle count NT,
//   float32 x 3NV positions, uint8 x 3NV colours (zero-padded to 4 bytes), uint32 x 3NT indices.
// parseCsm1 validates everything before a buffer is built and returns views onto the input
// (no copies), or throws an Error saying what is wrong.

export const CSM1_MAX_VERTICES = 1 << 24;
export const CSM1_MAX_TRIANGLES = 1 << 25;

export const pad4 = (n) => (n + 3) & ~3;

export function csm1ByteLength(nv, nt) {
  return 16 + 12 * nv + pad4(3 * nv) + 12 * nt;
}

export function parseCsm1(buffer) {
  if (!(buffer instanceof ArrayBuffer)) throw new Error('CSM1: not an ArrayBuffer');
  if (buffer.byteLength < 16) throw new Error(`CSM1: ${buffer.byteLength} bytes, shorter than the 16-byte header`);
  const dv = new DataView(buffer);
  const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
  if (magic !== 'CSM1') throw new Error(`CSM1: bad magic ${JSON.stringify(magic)}`);
  const version = dv.getUint32(4, true), nv = dv.getUint32(8, true), nt = dv.getUint32(12, true);
  if (nv > CSM1_MAX_VERTICES || nt > CSM1_MAX_TRIANGLES) throw new Error(`CSM1: ${nv} vertices / ${nt} triangles exceed the viewer's limits`);
  const expected = csm1ByteLength(nv, nt);
  if (buffer.byteLength !== expected)
    throw new Error(`CSM1: ${buffer.byteLength} bytes, header (${nv} vertices, ${nt} triangles) needs ${expected}`);
  if (nt > 0 && nv === 0) throw new Error('CSM1: triangles without vertices');
  const positions = new Float32Array(buffer, 16, 3 * nv);
  const colours = new Uint8Array(buffer, 16 + 12 * nv, 3 * nv);
  const indices = new Uint32Array(buffer, 16 + 12 * nv + pad4(3 * nv), 3 * nt);
  let maxIndex = 0;
  for (let i = 0; i < indices.length; i++) if (indices[i] > maxIndex) maxIndex = indices[i];
  if (nt > 0 && maxIndex >= nv) throw new Error(`CSM1: index ${maxIndex} out of range (${nv} vertices)`);
  for (let i = 0; i < positions.length; i++)
    if (!Number.isFinite(positions[i])) throw new Error(`CSM1: non-finite coordinate at vertex ${Math.floor(i / 3)}`);
  return { version, vertices: nv, triangles: nt, positions, colours, indices };
}
