"""The surrogate's lattice bookkeeping and its evaluation (issue 33): integer keys of lattice
points and squares, the walk down the levels, and the stop squares that answer a step's queries
in one lookup.

The interpolant ``I(s) = sum_p alpha_p phi_p(s)`` (:mod:`plantgrowth.unitcell.surrogate`) is
evaluated by a walk: level by level, the hats of the query's square Q_k whose corners are
points new on level k. The walk stops at the first level k whose Q_k has none (the quadtree's
finer points lie on and inside built squares, so no finer hat reaches Q_k). Every hat of a level
j <= k is bilinear on Q_j, which holds Q_k, so on this *stop square* Q_k

    I(s) = sum_c phi_c(t) I(q_c),   c = Q_k's four corners q_c, t = s's coordinates in Q_k,

and so is the estimate's term (the hats of the deepest built square's level). :class:`StopSquares`
keeps, per stop square met, I and that term at its corners (found by one walk of the square's
centre evaluated at its corners); a query in a known stop square, found by one search of its
Z-order code among the squares' code ranges (:func:`z_order`), is answered by one bilinear
combination instead of a walk over every level. A refinement drops the entries that meet the
hat supports of the points it adds (elsewhere I and the stop squares stay as they were). The
answer is the walk's to rounding (5e-16 relative measured: both place a query by the same
exact arithmetic, :func:`place`; tests/test_surrogate_continuity.py) and depends only on the
square and the interpolant, so it is the same on every rank.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

H0 = 0.1
"""Spacing of the coarsest lattice in (s1, s2); |s| = 0.1 is a 10% deviatoric stretch."""
MAX_LEVEL = 12
"""Finest level (spacing H0 / 4096); a query not resolved there takes that level's value."""
STEP = 2**MAX_LEVEL  # finest-lattice integers per coarsest spacing
OFFSET = 2**20  # finest-lattice integers are keyed in [-OFFSET, OFFSET): |s| < 25
OFFSETS = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])  # a square's corners, in its spacing
LOW = (1 << 21) - 1
CHUNK = 8192
"""Rows per pass of :meth:`LatticeSurrogate.relative_difference`: a chunk's differences and
squares (8192 x 38 values of the strain law) stay in cache."""


def place(s: np.ndarray) -> np.ndarray:
    """Stretches s in units of the coarsest spacing, rounded to 9 digits: round-off of Fg
    (s / H0 = 1e-17, or 0.9999999999) is on the lattice line, one exact point. One rounding
    for every level (a level's place is this times 2^level, exactly), so the squares holding a
    query nest: rounded per level, s = (6.4e-10, -3.9e-11) sat in the level-0 square at the
    origin but in the level-1 square below it, and a stop square's walk (from its centre) was
    not its queries' walk (scenes/gradient_nu_stress.toml at draft refined forever)."""
    return np.round(s / H0, 9)


def cell(s: np.ndarray, level: int | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The lower-left corner (finest integers, (n, 2)) of the square of ``level`` (one, or
    one per query) that holds each query s (n, 2), and its coordinates t (n, 2) in [0, 1)
    (:func:`place`: a square of level k + 1 lies in the one of level k)."""
    level = np.reshape(np.asarray(level, dtype=np.int64), (-1, 1))
    x = place(s) * 2.0**level  # exact: a power of 2
    base = np.floor(x)
    return base.astype(np.int64) * (STEP >> level), x - base


def hats(t: np.ndarray) -> np.ndarray:
    """Bilinear hat values (n, 4) of a square's corners (order of ``OFFSETS``) at t (n, 2)."""
    tx, ty = t[:, 0:1], t[:, 1:2]
    return np.hstack([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty])


def combine(weights: np.ndarray, rows: np.ndarray, table: np.ndarray) -> np.ndarray:
    """``sum_c weights[n, c] table[rows[n, c], :]`` (n, m): a sparse matrix of the weights (a
    row per query) times the table, each query's row summed in the order of its weights. No
    (n, c, m) gather: on the 1e5-dof tissue's 99,372 queries of 38 values, 9.5 ms against 21
    for batched products over chunks of 8192 queries (the same bits), which had in turn cut
    the whole gather of a fine mesh's 500,000 queries (3.3 s against 0.3 s, and 600 MB)."""
    n, c = weights.shape
    W = sp.csr_matrix(
        (weights.ravel(), rows.ravel(), np.arange(0, n * c + 1, c)), shape=(n, len(table))
    )
    return np.asarray(W @ table).reshape(n, table.shape[1])


def by_rows(ufunc: np.ufunc, a: np.ndarray) -> np.ndarray:
    """``ufunc.reduce(a, axis=1)`` of an (n, k) array with a small k, column by column: the same
    values (a maximum, a logical and/or is exact), but numpy's reduction over a short last axis
    is slow (25,000 x 4 values: 0.78 ms against 0.034 ms)."""
    out = a[:, 0].copy()
    for j in range(1, a.shape[1]):
        ufunc(out, a[:, j], out=out)
    return out


def find(keys: np.ndarray, wanted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions of ``wanted`` among the sorted ``keys`` (any valid row where absent) and
    whether each is there."""
    if not len(keys):
        return np.zeros(wanted.shape, dtype=np.int64), np.zeros(wanted.shape, dtype=bool)
    pos = np.minimum(np.searchsorted(keys, wanted), len(keys) - 1)
    return pos, keys[pos] == wanted


def point_key(ids: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """One int64 key per lattice point: table number, then the two finest integers."""
    if np.size(i) and max(np.abs(i).max(), np.abs(j).max()) >= OFFSET:
        raise ValueError(f"a growth stretch |s| >= {OFFSET * H0 / STEP:g}: off the lattice")
    return (ids << 42) | ((i + OFFSET) << 21) | (j + OFFSET)


def square_key(ids: np.ndarray, level: int | np.ndarray, corner: np.ndarray) -> np.ndarray:
    """One int64 key per square: table number, level, lower-left corner's finest integers."""
    return (ids << 46) | (np.asarray(level, dtype=np.int64) << 42) | (
        ((corner[..., 0] + OFFSET) << 21) | (corner[..., 1] + OFFSET)
    )  # fmt: skip


def key_integers(keys: np.ndarray) -> np.ndarray:
    """The finest-lattice integers (n, 2) held in the low 42 bits of point or square keys (a
    point's own, a square's lower-left corner's)."""
    return np.column_stack([((keys >> 21) & LOW) - OFFSET, (keys & LOW) - OFFSET])


def _spread(v: np.ndarray) -> np.ndarray:
    """The bits of v (< 2^21) moved to the even bit positions (bit b to bit 2 b)."""
    v = (v | (v << 16)) & 0x0000FFFF0000FFFF
    v = (v | (v << 8)) & 0x00FF00FF00FF00FF
    v = (v | (v << 4)) & 0x0F0F0F0F0F0F0F0F
    v = (v | (v << 2)) & 0x3333333333333333
    return (v | (v << 1)) & 0x5555555555555555


def z_order(ids: np.ndarray, integers: np.ndarray) -> np.ndarray:
    """One int64 code per table number and finest-lattice integers (n, 2): the table number,
    then the Z-order (bit-interleaved) code of the two offset integers. The codes of the finest
    squares inside an aligned square of level k are the 4^(MAX_LEVEL - k) ones from its
    lower-left corner's, so a square is a range of codes."""
    i, j = (integers[..., c].astype(np.int64) + OFFSET for c in (0, 1))
    return (np.asarray(ids, dtype=np.int64) << 42) | (_spread(i) << 1) | _spread(j)


def square_corners(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Table numbers (q,), levels (q,) and lower-left corners (q, 2) of squares' keys."""
    return keys >> 46, (keys >> 42) & 15, key_integers(keys)


def walk(
    squares: np.ndarray, keys: np.ndarray, surplus: np.ndarray, ids: np.ndarray,
    s: np.ndarray, targets: np.ndarray, strict: bool = False,
) -> dict[str, np.ndarray]:  # fmt: skip
    """One walk down the levels for n queries (sorted built squares' keys ``squares``, sorted
    point keys ``keys`` and their surpluses): the squares are those holding s (n, 2), the
    interpolant is evaluated at ``targets`` (n, r, 2) in them, given as places (:func:`place`;
    a lattice point's is exact, its finest integers / STEP). Returns ``values`` I (n, r, m)
    (``strict``: a KeyError off the built lattice), ``change`` the deepest built square S's term
    there, ``sum_c alpha_c phi_c`` over S's new corners, ``on_point`` (n, r) whether a target is
    a built point, ``level`` and ``square`` S's level and key (-1, 0: none), ``stop`` the level
    of the stop square Q_k (module docstring) and ``base`` (n, 4) whether Q_0's corners are
    built."""
    n, r = targets.shape[:2]
    values = np.zeros((n, r, surplus.shape[1] if len(keys) else 0))
    change = np.zeros_like(values)
    on_point = np.zeros((n, r), dtype=bool)
    level, square = np.full(n, -1), np.zeros(n, dtype=np.int64)
    stop, base = np.full(n, MAX_LEVEL), np.zeros((n, 4), dtype=bool)
    chain = np.ones(n, dtype=bool)  # every square so far on the query's chain is built
    alive = np.arange(n)
    for k in range(MAX_LEVEL + 1):
        corner = cell(s[alive], k)[0]
        asked = chain[alive]
        wanted = square_key(ids[alive[asked]], k, corner[asked])
        hit = find(squares, wanted)[1]
        level[alive[asked][hit]], square[alive[asked][hit]] = k, wanted[hit]
        chain[alive[asked][~hit]] = False
        points = corner[:, None, :] + OFFSETS[None] * (STEP >> k)
        t = np.clip(targets[alive] * 2.0**k - (corner // (STEP >> k))[:, None, :], 0.0, 1.0)
        weights = hats(t.reshape(-1, 2)).reshape(len(alive), r, 4)
        wanted = point_key(ids[alive, None], points[..., 0], points[..., 1])
        rows, built = find(keys, wanted)
        if k == 0:
            base[alive] = built
            if strict and not np.all(built[:, None, :] | (weights == 0.0)):
                raise KeyError("a query outside the refined lattice: refine() first")
        if k > 0:  # only the points new on this level carry its hats
            built &= ((points // (STEP >> k)) % 2).any(axis=-1)
        has = built.any(axis=1)  # the others have no finer hat either: done
        stop[alive[~has]] = k
        alive, built, weights, rows = alive[has], built[has], weights[has], rows[has]
        used = np.where(built[:, None, :], weights, 0.0).reshape(-1, 4)
        term = combine(used, np.repeat(rows, r, axis=0), surplus).reshape(
            len(alive), r, values.shape[2]
        )
        values[alive] += term
        own = level[alive] == k
        change[alive[own]] = term[own]
        on_point[alive] |= (built[:, None, :] & (weights == 1.0)).any(axis=-1)
        if not len(alive):
            break
    return {"values": values, "change": change, "on_point": on_point, "level": level,
            "square": square, "stop": stop, "base": base}  # fmt: skip


def supports(built: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per built square (keys): its table number and the closed box (lower and upper corners,
    finest integers) that the hats of its new points cover, the square's parent (the square
    itself at level 0) widened by the square's spacing h on every side."""
    table, level, corner = square_corners(np.asarray(built, dtype=np.int64))
    h = (STEP >> level)[:, None]
    span = np.where(level[:, None] > 0, 2 * h, h)  # the parent's side (level 0: its own)
    low = corner // span * span - h
    return table, low, low + span + 2 * h


def touched(built: np.ndarray, ids: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Whether each query (table numbers ids (n,), stretches s (n, 2)) lies in the box of a
    built square's new hats (:func:`supports`): only there can building the squares ``built``
    change the interpolant, the deepest built square or whether the query is a built point.
    Each box is tested against its own table's queries only (a geometry per coarse column
    builds squares of many tables in one pass)."""
    x = place(s) * STEP  # exact: a power of 2
    out = np.zeros(len(ids), dtype=bool)
    tables, low, high = supports(built)
    one_table = not len(ids) or (ids == ids[0]).all()  # the organ's: no sort, no copies
    order = None if one_table else np.argsort(ids, kind="stable")
    keys = ids if one_table else ids[order]
    first, last = (np.searchsorted(keys, tables, side=side) for side in ("left", "right"))
    for box in range(len(tables)):  # the queries of the box's table
        mine = slice(first[box], last[box]) if one_table else order[first[box] : last[box]]
        out[mine] |= np.all((x[mine] >= low[box]) & (x[mine] <= high[box]), axis=1)
    return out


class StopSquares:
    """I and the estimate's term at the corners of the stop squares met so far (module
    docstring); the owner drops the entries a refinement may change (:meth:`drop`)."""

    def __init__(self, norms: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        self._keys = np.zeros(0, dtype=np.int64)  # the entries' stop square keys
        self._columns: list[np.ndarray] | None = None  # per entry, as :meth:`_table` lists
        self._ranges_index: tuple[np.ndarray, ...] | None = None
        self._norms = norms  # (..., m) -> (..., segments): the estimate's norms per segment

    def drop(self, built: np.ndarray) -> None:
        """Forget the entries that squares just built (keys) may change: those of their table
        whose closed square meets a new point's hat support, the built square's parent (the
        square itself at level 0) widened by its spacing h on every side."""
        if not len(self._keys):
            return
        table, level, corner = square_corners(self._keys)
        width = (STEP >> level)[:, None]
        b_table, low, high = supports(built)
        meets = (table[:, None] == b_table[None]) & np.all(
            (corner[:, None, :] <= high[None]) & (corner[:, None, :] + width[:, None] >= low[None]),
            axis=-1,
        )  # (entries, built)
        kept = ~meets.any(axis=1)
        self._keys = self._keys[kept]
        self._columns = [column[kept] for column in self._columns]
        self._ranges_index = None

    def add(self, found: dict[str, np.ndarray], keys: np.ndarray) -> None:
        """Entries for the stop squares ``keys`` (q,, none known yet) from :func:`walk` at
        their corners, after the entries before (whose rows stay)."""
        values, change = found["values"], found["change"]
        columns = [values, change, found["on_point"], found["base"], found["level"],
                   found["square"]]  # fmt: skip
        if self._norms is not None:
            spread = self._norms(values[:, :, None, :] - values[:, None, :, :]).max(axis=2)
            columns += [self._norms(change), (self._norms(values) - spread).max(axis=1)]
        if len(self._keys):
            columns = [np.concatenate([old, new])
                       for old, new in zip(self._columns, columns, strict=True)]  # fmt: skip
        self._keys, self._columns = np.concatenate([self._keys, keys]), columns
        self._ranges_index = None

    def learn(
        self, squares: np.ndarray, keys: np.ndarray, surplus: np.ndarray, ids: np.ndarray,
        s: np.ndarray,
    ) -> None:  # fmt: skip
        """Walk queries (ids, s) to their stop squares on the lattice (sorted built squares'
        keys, sorted point keys and their surpluses), then each new stop square's centre to I
        and S's term at its corners (:func:`walk`), and keep them. One query per square of the
        level below the deepest built one is walked: queries in one such square share every
        coarser square (they nest), so their walks are one walk, which stops there at the
        latest (no point is new on that level). On the organ scene the 500,000 queries of a
        rank share a few thousand such squares."""
        depth = min(int(((squares >> 42) & 15).max()) + 1, MAX_LEVEL) if len(squares) else 0
        first = np.unique(square_key(ids, depth, cell(s, depth)[0]), return_index=True)[1]
        ids, s = ids[first], s[first]
        nowhere = np.empty((len(s), 0, 2))  # no targets: the stop levels only (no products)
        stop = walk(squares, keys, surplus, ids, s, nowhere)["stop"]
        stops, pick = np.unique(square_key(ids, stop, cell(s, stop)[0]), return_index=True)
        _, level, corner = square_corners(stops)
        step = (STEP >> level)[:, None]
        corners = corner[:, None, :] + OFFSETS[None] * step[:, None, :]
        centre = (corner + 0.5 * step) * (H0 / STEP)
        self.add(walk(squares, keys, surplus, ids[pick], centre, corners / STEP), stops)

    def through(
        self, lattice: Callable[[], tuple[np.ndarray, np.ndarray, np.ndarray]],
        ids: np.ndarray, s: np.ndarray, strict: bool = False, quiet: np.ndarray | None = None,
    ) -> dict[str, np.ndarray]:  # fmt: skip
        """:meth:`answer` for queries (ids, s): one lookup of each query's stop square, the
        ones not met before learnt first (:meth:`learn`) from ``lattice()``, the squares,
        point keys and surpluses."""
        rows, t = self.lookup(ids, s)
        miss = np.flatnonzero(rows < 0)
        if len(miss):  # new entries come after the rows found: the missed ones looked up
            self.learn(*lattice(), ids[miss], s[miss])
            rows[miss], t[miss] = self.lookup(ids[miss], s[miss])
        return self.answer(rows, t, s, strict, quiet)

    def _table(self) -> tuple[np.ndarray, ...]:
        """Of the entries (at least one): corner rows of I and of S's term (each (4 E, m)), per
        entry its corner flags, Q_0's corners' built flags, S's level and key, and (with
        ``norms``, else None) the norms of S's term at its corners (4 E, segments) and a lower
        bound of |I| over the square (E, segments): ``max_c (|I(c)| - max_c' |I(c') - I(c)|)``,
        as I is a convex combination of the corners' values there. Views of the columns."""
        values, change, *rest = self._columns[:6]
        e, m = len(self._keys), values.shape[2]
        norms = None
        if self._norms is not None:
            corner_norms, size = self._columns[6:]
            norms = corner_norms.reshape(e * 4, -1), size  # as the rows
        return (*(a.reshape(e * 4, m) for a in (values, change)), *rest, norms)

    def lookup(self, ids: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per query: its entry's row (-1: no known stop square holds it) and its coordinates t
        (n, 2) in that square: the coarsest entry that holds it, found by one search of its
        finest-lattice Z-order code among the ranges of the entries (:meth:`_ranges`). A query
        off the lattice (|s| >= 25) is held by none: :meth:`learn`'s walk raises for it."""
        x = place(s)
        finest = np.floor(x * STEP)  # exact: a power of 2
        inside = by_rows(np.logical_and, np.abs(finest) < OFFSET)
        code = z_order(ids, np.where(inside[:, None], finest, 0.0).astype(np.int64))
        starts, ends, entry = self._ranges()
        pos = np.searchsorted(starts, code, side="right") - 1
        hit = inside & (pos >= 0)
        hit[hit] = code[hit] < ends[pos[hit]]
        rows = np.where(hit, entry[np.maximum(pos, 0)] if len(entry) else -1, -1)
        level = (self._keys[np.maximum(rows, 0)] >> 42) & 15 if len(entry) else rows
        scaled = x * 2.0 ** level[:, None]  # exact, as :func:`cell`'s
        return rows, scaled - np.floor(scaled)

    def _ranges(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The entries' Z-order ranges of finest-lattice codes (:func:`z_order`), sorted, and
        each range's entry row: an aligned square of level k covers the 4^(MAX_LEVEL - k) codes
        from its lower-left corner's. An entry inside a coarser one (their ranges nest) is left
        out: :meth:`lookup` answers from the coarsest entry holding a query."""
        if self._ranges_index is None:  # (None again after a change)
            table, level, corner = square_corners(self._keys)
            starts = z_order(table, corner)
            ends = starts + (1 << (2 * (MAX_LEVEL - level)))
            order = np.lexsort((-ends, starts))  # by start, a coarser entry first
            starts, ends = starts[order], ends[order]
            reach = np.maximum.accumulate(ends)
            kept = np.ones(len(order), dtype=bool)
            kept[1:] = starts[1:] >= reach[:-1]  # aligned squares: overlap means inside
            self._ranges_index = starts[kept], ends[kept], order[kept]
        return self._ranges_index

    def answer(
        self, rows: np.ndarray, t: np.ndarray, s: np.ndarray, strict: bool,
        quiet: np.ndarray | None = None,
    ) -> dict[str, np.ndarray]:  # fmt: skip
        """The bilinear answers of queries in known stop squares (entry ``rows``, coordinates
        t): values, change, on_point, level, square (as :func:`walk`, r = 1). With ``quiet``
        (n,) thresholds, also ``bound`` (inf without ``norms``), a bound of each query's estimate
        ``|term| / |I|`` (largest over the segments): the term is a convex combination of the
        corners' terms, so ``|term| <= sum_c phi_c |term(c)|``, over the square's lower bound
        of |I| (:meth:`_table`); only the queries ``loud`` (indices) whose bound is not below
        their threshold and whose S has an estimate (level >= 1) have their term summed:
        ``change`` holds theirs only."""
        values, change, corner_point, base, level, square, norms = self._table()
        weights = hats(t)
        if strict and not np.all(base[rows] | (hats(cell(s, 0)[1]) == 0.0)):
            raise KeyError("a query outside the refined lattice: refine() first")
        corners = rows[:, None] * 4 + np.arange(4)[None]  # an entry's four corner rows
        found = {
            "values": combine(weights, corners, values),
            "level": level[rows],
            "square": square[rows],
            "on_point": by_rows(np.logical_or, corner_point[rows] & (weights == 1.0)),
        }
        if quiet is None:
            found["change"] = combine(weights, corners, change)
            return found
        found["bound"] = np.full(len(rows), np.inf)
        if norms is not None:
            top = combine(weights, corners, norms[0])
            size = norms[1][rows]
            ratio = np.divide(top, size, out=np.full(top.shape, np.inf), where=size > 0.0)
            found["bound"] = by_rows(np.maximum, np.where(top == 0.0, 0.0, ratio))
        loud = np.flatnonzero((found["bound"] >= quiet) & (found["level"] >= 1))
        found["loud"], found["change"] = loud, combine(weights[loud], corners[loud], change)
        return found
