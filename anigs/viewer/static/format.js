// Reader of the anigs compact animated scene (anigs-compact/1; layout in anigs/viewer/compact.py).
"use strict";
var ANIGS = window.ANIGS || (window.ANIGS = {});

ANIGS.crc32 = (function () {
  const table = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xEDB88320 ^ (c >>> 1) : c >>> 1;
    table[n] = c >>> 0;
  }
  return function (bytes) {
    let c = 0xFFFFFFFF;
    for (let i = 0; i < bytes.length; i++) c = table[(c ^ bytes[i]) & 255] ^ (c >>> 8);
    return (c ^ 0xFFFFFFFF) >>> 0;
  };
})();

// Parse an ArrayBuffer: {header, arrays: {name: TypedArray}} or throw an Error saying what is wrong.
ANIGS.parseCompact = function (buf) {
  if (buf.byteLength < 16) throw new Error("scene file is too short (" + buf.byteLength + " bytes)");
  const magic = new TextDecoder().decode(new Uint8Array(buf, 0, 8));
  if (magic !== "ANIGSCMP") throw new Error("not an anigs compact scene (magic " + JSON.stringify(magic) + ")");
  const dv = new DataView(buf);
  const version = dv.getUint32(8, true), hlen = dv.getUint32(12, true);
  if (version !== 1) throw new Error("compact format version " + version + " is not supported");
  if (buf.byteLength < 16 + hlen) throw new Error("scene file truncated in the header");
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 16, hlen)));
  const start = 16 + hlen;
  if (buf.byteLength < start + header.data_bytes) {
    throw new Error("scene file truncated (" + buf.byteLength + " of " + (start + header.data_bytes) + " bytes)");
  }
  if (ANIGS.crc32(new Uint8Array(buf, start, header.data_bytes)) !== header.crc32) {
    throw new Error("scene file corrupted (CRC-32 mismatch)");
  }
  const types = {"<f4": Float32Array, "<u4": Uint32Array, "<i4": Int32Array};
  const arrays = {};
  for (const [name, spec] of Object.entries(header.arrays)) {
    const T = types[spec.dtype];
    if (!T) throw new Error("array " + name + ": dtype " + spec.dtype + " not supported");
    const count = spec.shape.reduce((a, b) => a * b, 1);
    arrays[name] = new T(buf, start + spec.offset, count);
  }
  return {header, arrays};
};

ANIGS.base64ToBuffer = function (b64) {
  const s = atob(b64), out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out.buffer;
};
