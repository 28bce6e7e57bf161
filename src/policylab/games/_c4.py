"""Compiled Connect Four kernels (numba): Pons-style negamax solver and random playouts.

Bitboards follow :mod:`policylab.games.connect_four`: ``cur`` is the player to move's
stones, ``mask`` all stones, column c at bits 7c..7c+5. The solver is negamax with
alpha-beta on a null window (iterative deepening of the score bounds), a transposition
table of upper bounds keyed by ``cur + mask``, pruning of moves that lose at once, and
move ordering by the number of winning cells a move creates, centre columns first
(the design of Pascal Pons' Connect Four solver). UCT search runs whole here too:
its tree in arrays, its playouts on the bitboards.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = ["TT_SIZE", "new_table", "rollout", "solve", "solve_moves", "uct_search"]

W = 7
H = 6
H1 = H + 1
CELLS = W * H
MIN_SCORE = -(CELLS // 2) + 3  # -18: the fastest possible loss
MAX_SCORE = (CELLS + 1) // 2 - 3  # 18
TT_SIZE = (1 << 23) + 9  # a prime; 8 million entries (72 MB)

_U1 = np.uint64(1)
BOTTOM = np.uint64(sum(1 << (c * H1) for c in range(W)))
BOARD = np.uint64(sum(((1 << H) - 1) << (c * H1) for c in range(W)))
ORDER = np.array([3, 2, 4, 1, 5, 0, 6], dtype=np.int64)  # centre columns first


def new_table(size: int = TT_SIZE) -> tuple[NDArray[np.uint64], NDArray[np.int8]]:
    """An empty transposition table: keys and stored values (0: empty)."""
    return np.zeros(size, dtype=np.uint64), np.zeros(size, dtype=np.int8)


@nb.njit(cache=True, inline="always")
def _popcount(x: np.uint64) -> int:
    n = 0
    while x:
        x &= x - _U1
        n += 1
    return n


@nb.njit(cache=True)
def winning_cells(pos: np.uint64, mask: np.uint64) -> np.uint64:
    """The empty cells where one more stone of ``pos`` makes four in a line."""
    s1 = np.uint64(1)
    s2 = np.uint64(2)
    s3 = np.uint64(3)
    r = (pos << s1) & (pos << s2) & (pos << s3)  # vertical
    for d in (H1, H, H + 2):  # horizontal, the two diagonals
        u = np.uint64(d)
        u2 = np.uint64(2 * d)
        u3 = np.uint64(3 * d)
        p = (pos << u) & (pos << u2)
        r |= p & (pos << u3)
        r |= p & (pos >> u)
        p = (pos >> u) & (pos >> u2)
        r |= p & (pos << u)
        r |= p & (pos >> u3)
    return r & (BOARD ^ mask)


@nb.njit(cache=True, inline="always")
def _possible(mask: np.uint64) -> np.uint64:
    return (mask + BOTTOM) & BOARD


@nb.njit(cache=True, inline="always")
def _column(c: int) -> np.uint64:
    return ((_U1 << np.uint64(H)) - _U1) << np.uint64(c * H1)


@nb.njit(cache=True)
def _non_losing(cur: np.uint64, mask: np.uint64) -> np.uint64:
    """Moves that do not let the opponent win at once (0 if every move loses)."""
    possible = _possible(mask)
    opp_win = winning_cells(cur ^ mask, mask)
    forced = possible & opp_win
    if forced:
        if forced & (forced - _U1):
            return np.uint64(0)  # two threats: cannot block both
        possible = forced
    return possible & ~(opp_win >> _U1)  # never play just below an opponent's winning cell


@nb.njit(cache=True)
def _negamax(
    cur: np.uint64,
    mask: np.uint64,
    n: int,
    alpha: int,
    beta: int,
    keys: NDArray[np.uint64],
    vals: NDArray[np.int8],
    nodes: NDArray[np.int64],
) -> int:
    """Score in [alpha, beta]-window semantics; the side to move cannot win at once."""
    nodes[0] += 1
    nxt = _non_losing(cur, mask)
    if nxt == 0:
        return -((CELLS - n) // 2)
    if n >= CELLS - 2:
        return 0
    lo = -((CELLS - 2 - n) // 2)
    if alpha < lo:
        alpha = lo
        if alpha >= beta:
            return alpha
    hi = (CELLS - 1 - n) // 2
    key = cur + mask
    slot = key % np.uint64(keys.shape[0])
    if vals[slot] != 0 and keys[slot] == key:
        hi = int(vals[slot]) + MIN_SCORE - 1
    if beta > hi:
        beta = hi
        if alpha >= beta:
            return beta
    # order the candidate moves by how many winning cells they leave us (insertion sort)
    moves = np.zeros(W, dtype=np.uint64)
    scores = np.zeros(W, dtype=np.int64)
    k = 0
    for i in range(W):
        mv = nxt & _column(ORDER[i])
        if mv:
            sc = _popcount(winning_cells(cur | mv, mask))
            j = k
            while j > 0 and scores[j - 1] < sc:
                moves[j] = moves[j - 1]
                scores[j] = scores[j - 1]
                j -= 1
            moves[j] = mv
            scores[j] = sc
            k += 1
    for i in range(k):
        mv = moves[i]
        new_mask = mask | mv
        s = -_negamax(cur ^ mask, new_mask, n + 1, -beta, -alpha, keys, vals, nodes)
        if s >= beta:
            return s
        if s > alpha:
            alpha = s
    keys[slot] = key
    vals[slot] = alpha - MIN_SCORE + 1
    return alpha


@nb.njit(cache=True)
def solve(
    cur: np.uint64,
    mask: np.uint64,
    n: int,
    keys: NDArray[np.uint64],
    vals: NDArray[np.int8],
    nodes: NDArray[np.int64],
) -> int:
    """The exact score of a non-terminal position with ``n`` stones (Pons' convention).

    Positive: the player to move wins, 22 - k if with their k-th stone; negative: they
    lose the same way; 0: a draw with perfect play on both sides.
    """
    if winning_cells(cur, mask) & _possible(mask):
        return (CELLS + 1 - n) // 2
    lo = -((CELLS - n) // 2)
    hi = (CELLS + 1 - n) // 2
    while lo < hi:  # narrow [lo, hi] by null-window searches, probing near 0 first
        med = lo + (hi - lo) // 2
        if med <= 0 and lo // 2 < med:
            med = lo // 2
        elif med >= 0 and hi // 2 > med:
            med = hi // 2
        r = _negamax(cur, mask, n, med, med + 1, keys, vals, nodes)
        if r <= med:
            hi = r
        else:
            lo = r
    return lo


@nb.njit(cache=True)
def solve_moves(
    cur: np.uint64,
    mask: np.uint64,
    n: int,
    keys: NDArray[np.uint64],
    vals: NDArray[np.int8],
    nodes: NDArray[np.int64],
) -> NDArray[np.int64]:
    """The score of every column from the mover's view (-1000 where the column is full)."""
    out = np.full(W, -1000, dtype=np.int64)
    win = winning_cells(cur, mask)
    possible = _possible(mask)
    for c in range(W):
        mv = possible & _column(c)
        if not mv:
            continue
        if mv & win:
            out[c] = (CELLS + 1 - n) // 2
        elif n + 1 == CELLS:
            out[c] = 0
        else:
            out[c] = -solve(cur ^ mask, mask | mv, n + 1, keys, vals, nodes)
    return out


@nb.njit(cache=True, inline="always")
def _aligned(pos: np.uint64) -> bool:
    """True if ``pos`` holds four in a line (any direction)."""
    for d in (1, H, H1, H + 2):  # vertical, the diagonal /, horizontal, the diagonal \
        u = np.uint64(d)
        m = pos & (pos >> u)
        if m & (m >> np.uint64(2 * d)):
            return True
    return False


@nb.njit(cache=True, inline="always")
def _random_move(mask: np.uint64) -> np.uint64:
    """The cell a uniformly random legal move fills (0 if the board is full)."""
    possible = _possible(mask)
    k = 0
    for c in range(W):
        if possible & _column(c):
            k += 1
    if k == 0:
        return np.uint64(0)
    r = np.random.randint(k)
    for c in range(W):
        mv = possible & _column(c)
        if mv:
            if r == 0:
                return mv
            r -= 1
    return np.uint64(0)


@nb.njit(cache=True)
def _playout(cur: np.uint64, mask: np.uint64) -> int:
    """Random play from a non-terminal position: +1 if the player to move wins, -1, 0 a draw."""
    sign = 1
    while True:
        mv = _random_move(mask)
        if mv == 0:
            return 0
        mask = mask | mv
        if _aligned(cur | mv):
            return sign
        cur = (cur | mv) ^ mask  # the other player's stones: they move next
        sign = -sign


@nb.njit(cache=True)
def rollout(cur: np.uint64, mask: np.uint64, seed: int) -> int:
    """Uniformly random moves to the end: +1 if the player to move now wins, -1, or 0."""
    np.random.seed(seed)
    return _playout(cur, mask)


@nb.njit(cache=True)
def _new_node(
    i: int,
    cur: np.uint64,
    mask: np.uint64,
    node_cur: NDArray[np.uint64],
    node_mask: NDArray[np.uint64],
    untried: NDArray[np.int8],
    n_untried: NDArray[np.int64],
) -> None:
    """Node ``i`` for the position (cur, mask): its legal columns, shuffled, left to try."""
    node_cur[i] = cur
    node_mask[i] = mask
    possible = _possible(mask)
    k = 0
    for c in range(W):
        if possible & _column(c):
            untried[i, k] = c
            k += 1
    for j in range(k - 1, 0, -1):  # Fisher-Yates
        r = np.random.randint(j + 1)
        t = untried[i, j]
        untried[i, j] = untried[i, r]
        untried[i, r] = t
    n_untried[i] = k


@nb.njit(cache=True)
def uct_search(
    cur: np.uint64, mask: np.uint64, simulations: int, c: float, seed: int
) -> NDArray[np.int64]:
    """UCT with random playouts from a non-terminal position: the root's visit counts per column.

    The tree lives in arrays (one node per simulation at most). Selection descends
    through nodes with no untried move by UCB1, ``w / n + c sqrt(ln N / n)``, each
    node keeping the total outcome ``w`` for the player who moved into it; expansion
    adds one child (the next of the node's shuffled legal columns); a playout of
    uniformly random moves scores it (a finished game scores its outcome); the
    outcome is backed up the path, negated at each level.
    """
    np.random.seed(seed)
    size = simulations + 1
    node_cur = np.empty(size, dtype=np.uint64)
    node_mask = np.empty(size, dtype=np.uint64)
    visits = np.zeros(size, dtype=np.int64)
    total = np.zeros(size, dtype=np.float64)
    terminal_value = np.zeros(size, dtype=np.float64)
    is_terminal = np.zeros(size, dtype=np.bool_)
    untried = np.empty((size, W), dtype=np.int8)
    n_untried = np.zeros(size, dtype=np.int64)
    children = np.empty((size, W), dtype=np.int64)  # in the order they were added
    child_col = np.empty((size, W), dtype=np.int64)
    n_children = np.zeros(size, dtype=np.int64)
    path = np.empty(CELLS + 2, dtype=np.int64)
    # an int64 index, not the literal 0 (which would compile a second copy)
    _new_node(int(0), cur, mask, node_cur, node_mask, untried, n_untried)  # noqa: UP018, RUF046
    used = 1
    for _ in range(simulations):
        node = 0
        depth = 0
        path[0] = 0
        while n_untried[node] == 0 and n_children[node] > 0:
            log_n = np.log(visits[node])
            best = -np.inf
            best_child = node
            for k in range(n_children[node]):
                ch = children[node, k]
                score = total[ch] / visits[ch] + c * np.sqrt(log_n / visits[ch])
                if score > best:
                    best = score
                    best_child = ch
            node = best_child
            depth += 1
            path[depth] = node
        if n_untried[node] > 0:  # expansion
            n_untried[node] -= 1
            col = untried[node, n_untried[node]]
            p_cur = node_cur[node]
            p_mask = node_mask[node]
            mv = _possible(p_mask) & _column(col)
            new = used
            used += 1
            new_mask = p_mask | mv
            new_cur = p_cur ^ p_mask  # the opponent moves next
            n_new = _popcount(new_mask)
            node_cur[new] = new_cur
            node_mask[new] = new_mask
            n_untried[new] = 0
            if _aligned(p_cur | mv):
                is_terminal[new] = True
                terminal_value[new] = -1.0  # the player to move there has lost
            elif n_new == CELLS:
                is_terminal[new] = True
                terminal_value[new] = 0.0
            else:
                is_terminal[new] = False
                _new_node(int(new), new_cur, new_mask, node_cur, node_mask, untried, n_untried)
            children[node, n_children[node]] = new
            child_col[node, n_children[node]] = col
            n_children[node] += 1
            node = new
            depth += 1
            path[depth] = node
        if is_terminal[node]:
            value = terminal_value[node]
        else:
            value = float(_playout(node_cur[node], node_mask[node]))
        for d in range(depth, -1, -1):  # each node keeps the outcome for who moved into it
            value = -value
            nd = path[d]
            visits[nd] += 1
            total[nd] += value
    counts = np.zeros(W, dtype=np.int64)
    for k in range(n_children[0]):
        counts[child_col[0, k]] = visits[children[0, k]]
    return counts
