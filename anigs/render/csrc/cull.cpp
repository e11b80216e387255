// Tight culling for the CPU rasterizer (included by raster.cpp, inside its anonymous namespace).
//
// A splat's pixel box (rects, from projection) bounds its ellipse axis-aligned; a thin or tilted
// splat's ellipse covers a small part of it. The pixels that can pass the alpha >= 1/255 test lie
// inside the ellipse
//   q(d) = A dx^2 + 2 B dx dy + C dy^2 <= level,  level = 2 ln(255 o),
// so the binning skips the tiles of the box that the ellipse misses, and stores for each kept
// (tile, splat) pair the sub-rectangle of the tile that it reaches (rows, then columns); the
// compositing passes (forward, backward, blend weights) only visit that sub-rectangle.
//
// Exactness: the culling uses a widened level L = level (1 + 1e-4 + 4e-5 / (1 - rho^2)) + 1e-4,
// rho^2 = B^2 / (A C). The kernel's float exponent errs by a few ulp (~1e-6 relative) of
// A dx^2 + C dy^2 + 2 |B dx dy|, which is at most 4 q / (1 - rho^2) near the ellipse, so every pixel
// the float kernel draws lies inside L with a tenfold margin: the culled pixels and pairs are
// exactly those that add nothing, and the images are bit for bit the box-only kernel's. Splats too
// thin to bound in double (1 - rho^2 < 1e-6) keep their whole box.

// A splat's ellipse in double: centre, conic, det = A C - B^2, widened level L, and its extreme
// points: (+-xt, +-ye) the top and bottom (the largest |dy|, ye), (+-xe, +-yt) the right and left
// ends (the largest |dx|, xe). ok = false: no culling.
struct Ell {
  double mx, my, A, B, C, det, L, xe, yt, ye, xt;
  bool ok;
};

inline Ell ellipse_of(float mx, float my, float A, float B, float C, float o) {
  Ell e;
  e.mx = mx; e.my = my; e.A = A; e.B = B; e.C = C;
  e.det = e.A * e.C - e.B * e.B;  // exact products of floats
  const double ac = e.A * e.C;
  e.ok = e.A > 0.0 && e.C > 0.0 && e.det > 1e-6 * ac && std::isfinite(e.det);
  if (!e.ok) return e;
  const double level = 2.0 * double(std::log(std::max(255.f * o, 1.f)));
  e.L = level * (1.0 + 1e-4 + 4e-5 * ac / e.det) + 1e-4;
  e.ye = std::sqrt(e.L * e.A / e.det);
  e.xt = -e.B * e.ye / e.A;
  e.xe = std::sqrt(e.L * e.C / e.det);
  e.yt = -e.B * e.xe / e.C;
  return e;
}

// The v range [lo, hi] of the points of the ellipse P u^2 + 2 Q u v + R v^2 <= L whose u lies in
// [a, b], given its top point (ut, ve) (the bottom one is (-ut, -ve)); false when there are none.
// The ellipse's upper boundary is concave in u (its lower one convex), so its maximum over the
// strip is at the top point's u clamped to the strip (the minimum at the bottom point's);
// outside the ellipse's own u range that clamped u has no root.
inline bool strip_span(double Q, double R, double det, double L, double ut, double ve, double a, double b,
                       double& lo, double& hi) {
  if (a <= ut && ut <= b) {
    hi = ve;
  } else {
    const double u = ut < a ? a : b, d = R * L - det * u * u;  // quarter discriminant at u
    if (d < 0.0) return false;
    hi = (-Q * u + std::sqrt(d)) / R;
  }
  if (a <= -ut && -ut <= b) {
    lo = -ve;
  } else {
    const double u = -ut < a ? a : b, d = R * L - det * u * u;
    if (d < 0.0) return false;
    lo = (-Q * u - std::sqrt(d)) / R;
  }
  return lo <= hi;
}

// Pixel indices i in [i0, i1) whose centre c + i + 0.5 - centre lies in [lo, hi].
inline void clip_range(double centre, double lo, double hi, int& i0, int& i1) {
  lo = std::min(std::max(centre + lo - 0.5, -1e9), 1e9);
  hi = std::min(std::max(centre + hi - 0.5, -1e9), 1e9);
  i0 = std::max(i0, int(std::ceil(lo)));
  i1 = std::min(i1, int(std::floor(hi)) + 1);
}

// Narrow the pixel range [b0, b1) along one axis to what the ellipse reaches within [a0, a1) along
// the other: rows within columns (rows = true: a is x, b is y) or columns within rows; false if none.
inline bool span_within(const Ell& e, bool rows, int a0, int a1, int& b0, int& b1) {
  if (!e.ok) return b0 < b1 && a0 < a1;
  const double ma = rows ? e.mx : e.my;
  double lo, hi;
  if (!strip_span(e.B, rows ? e.C : e.A, e.det, e.L, rows ? e.xt : e.yt, rows ? e.ye : e.xe, a0 + 0.5 - ma,
                  a1 - 0.5 - ma, lo, hi)) return false;
  clip_range(rows ? e.my : e.mx, lo, hi, b0, b1);
  return b0 < b1;
}

// Narrow pixel rows [y0, y1) to those the ellipse reaches within columns [x0, x1); false if none.
inline bool rows_within(const Ell& e, int x0, int x1, int& y0, int& y1) { return span_within(e, true, x0, x1, y0, y1); }

// Narrow pixel columns [x0, x1) to those the ellipse reaches within rows [y0, y1); false if none.
inline bool cols_within(const Ell& e, int y0, int y1, int& x0, int& x1) { return span_within(e, false, y0, y1, x0, x1); }

// Whether a pixel box is one tile high or one tile wide. The box bounds the ellipse tightly, so
// the ellipse crosses the box's whole width and height and reaches each of its tiles: such a box
// is kept whole (each of its tiles, all of the box in each), without the culling's arithmetic.
inline bool uncut(const int32_t* r) { return r[0] / TILE == (r[2] - 1) / TILE || r[1] / TILE == (r[3] - 1) / TILE; }
inline int box_tiles(const int32_t* r) {
  return ((r[2] - 1) / TILE - r[0] / TILE + 1) * ((r[3] - 1) / TILE - r[1] / TILE + 1);
}

// The tiles of a splat's box (not uncut) that its ellipse reaches: for each tile row
// ty of the box, the tile columns [tx0, tx1) (empty: tx0 >= tx1). fn(ty, tx0, tx1, y0, y1, x0, x1) gets the row's pixel
// band [y0, y1) and the columns [x0, x1) the ellipse reaches in it.
template <class Fn> inline void for_tile_rows(const Ell& e, const int32_t* r, Fn&& fn) {
  for (int ty = r[1] / TILE; ty <= (r[3] - 1) / TILE; ++ty) {
    const int y0 = std::max(r[1], ty * TILE), y1 = std::min(r[3], ty * TILE + TILE);
    int x0 = r[0], x1 = r[2];
    if (!cols_within(e, y0, y1, x0, x1)) continue;
    fn(ty, x0 / TILE, (x1 - 1) / TILE + 1, y0, y1, x0, x1);
  }
}

// Number of (tile, splat) pairs of a splat (mean m [2], conic c [3], opacity o) with box r.
inline int culled_tiles(const float* m, const float* c, float o, const int32_t* r) {
  if (uncut(r)) return box_tiles(r);
  int n = 0;
  for_tile_rows(ellipse_of(m[0], m[1], c[0], c[1], c[2], o), r,
                [&](int, int tx0, int tx1, int, int, int, int) { n += tx1 - tx0; });
  return n;
}

// A pair's sub-rectangle of its tile, packed as four bytes (x0, y0, x1, y1 relative to the tile's
// corner, 0..16); x0 == x1 marks a pair whose rectangle has no pixel centre inside the ellipse.
inline int32_t pack_rect(int x0, int y0, int x1, int y1) {
  return int32_t(uint32_t(x0) | (uint32_t(y0) << 8) | (uint32_t(x1) << 16) | (uint32_t(y1) << 24));
}
inline bool unpack_rect(int32_t p, int px0, int py0, int& x0, int& y0, int& x1, int& y1) {
  const uint32_t u = uint32_t(p);
  x0 = px0 + int(u & 255u); y0 = py0 + int((u >> 8) & 255u);
  x1 = px0 + int((u >> 16) & 255u); y1 = py0 + int(u >> 24);
  return x0 < x1 && y0 < y1;
}

// Whether the pixel centres at the four corners of [x0, x1) x [y0, y1) lie inside the ellipse:
// then, the ellipse being convex, all of them do and nothing narrows.
inline bool corners_inside(const Ell& e, int x0, int y0, int x1, int y1) {
  if (!e.ok) return true;
  const double dx[2] = {x0 + 0.5 - e.mx, x1 - 0.5 - e.mx}, dy[2] = {y0 + 0.5 - e.my, y1 - 0.5 - e.my};
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      if (e.A * dx[i] * dx[i] + 2.0 * e.B * dx[i] * dy[j] + e.C * dy[j] * dy[j] > e.L) return false;
  return true;
}

// The packed sub-rectangle of tile column tx for a row band [y0, y1) whose reached columns are
// [x0, x1) (as for_tile_rows gives them): the tile's columns, then, for a tilted ellipse (rho^2 >=
// 1/4: the band's box cuts an upright one tightly already) whose corners are not all inside, the
// rows reached in them and the columns reached in those rows.
inline int32_t tile_rect(const Ell& e, int tx, int ty, int y0, int y1, int x0, int x1) {
  const int px0 = tx * TILE, py0 = ty * TILE;
  int cx0 = std::max(x0, px0), cx1 = std::min(x1, px0 + TILE), ry0 = y0, ry1 = y1;
  if (e.B * e.B < 0.25 * e.A * e.C || corners_inside(e, cx0, ry0, cx1, ry1))
    return pack_rect(cx0 - px0, ry0 - py0, cx1 - px0, ry1 - py0);
  if (!rows_within(e, cx0, cx1, ry0, ry1) || !cols_within(e, ry0, ry1, cx0, cx1)) return pack_rect(0, 0, 0, 0);
  return pack_rect(cx0 - px0, ry0 - py0, cx1 - px0, ry1 - py0);
}

// Lists the (tile, splat) pairs of splat s in binning order (tile rows, then columns): tile
// index ty * TX + tx into tile[i] and packed sub-rectangle into rect[i]. Returns their number,
// culled_tiles() of the splat.
inline int splat_pairs(const Rec& s, int TX, int32_t* tile, int32_t* rect) {
  const int32_t box[4] = {s.x0, s.y0, s.x1, s.y1};
  int n = 0;
  if (uncut(box)) {  // kept whole
    for (int ty = s.y0 / TILE; ty <= (s.y1 - 1) / TILE; ++ty)
      for (int tx = s.x0 / TILE; tx <= (s.x1 - 1) / TILE; ++tx) {
        const int px0 = tx * TILE, py0 = ty * TILE;
        tile[n] = ty * TX + tx;
        rect[n++] = pack_rect(std::max(s.x0, px0) - px0, std::max(s.y0, py0) - py0, std::min(s.x1, px0 + TILE) - px0,
                              std::min(s.y1, py0 + TILE) - py0);
      }
    return n;
  }
  const Ell e = ellipse_of(s.mx, s.my, s.A, s.B, s.C, s.o);
  for_tile_rows(e, box, [&](int ty, int tx0, int tx1, int y0, int y1, int x0, int x1) {
    for (int tx = tx0; tx < tx1; ++tx) {
      tile[n] = ty * TX + tx;
      rect[n++] = tile_rect(e, tx, ty, y0, y1, x0, x1);
    }
  });
  return n;
}
