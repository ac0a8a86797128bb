"""madmom's downbeat DBN with its Viterbi decode compiled: the same hidden Markov models, the same answers.

madmom's Cython `HiddenMarkovModel.viterbi` was about a third of the cold analysis once the networks were
compiled (madmom_nets): for every frame it walks every transition of a sparse model through a general
loop, though 98 % of the states have one transition, from the state before them, and only the first state
of each beat has more (up to 36). Here the same sums in the same order (float64, previous + transition +
observation) and the same strict comparisons in madmom's transition order, so the same path and log
probability, with that structure used: one vectorised pass gives every state its first transition, the
few irregular states are redone in full, the states with a choice compare their transitions in a second
vectorised pass (a dense table per beat: the previous beat's last states against this beat's first), and
back-pointers are kept only for the states with a choice (the rest came from their one predecessor), ~60x
less memory than madmom's [frames, states] table. ~10x faster than madmom's decode. Hand-written because
no maintained library decodes madmom's transition models; the tests compare paths and log probabilities
with madmom's own decode exactly.
"""

from __future__ import annotations

import warnings

import numpy as np
from numba import njit
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from .. import jit

LANES = 16  # the multi states' loop runs 2 vectors of 8 float64 a pass: blocks padded to whole passes, so
# that no scalar remainder follows each source's pass (a fifth of the time with 60-state blocks)

@njit(cache=True, nogil=True, error_model="numpy")
def _viterbi(  # pragma: no cover - compiled
    densities: np.ndarray, om_pointers: np.ndarray, first_state: np.ndarray, first_log_prob: np.ndarray,
    irregular: np.ndarray, multi: np.ndarray, blocks: np.ndarray, sources: np.ndarray, rows: np.ndarray,
    log_probs: np.ndarray, log_initial: np.ndarray, bt: np.ndarray,
) -> tuple[int, float]:
    """madmom's Viterbi forward pass. Every state takes its first transition as if it came from the state
    before it and saw no beat (a loop the compiler vectorises); the `irregular` states, for which that is not
    so, are redone. The `multi` states, grouped into blocks that share their sources, compare all their
    transitions in madmom's order (ascending source state): each source of a block in turn against every
    multi state of the block, from a dense table, -inf where a state has no such transition (never
    better), so that the loop vectorises (indirect loads would not); back-pointers go to bt [T, len(multi)].
    blocks [B + 1, 2]: where each block's multi states and sources start, a block padded to whole LANES
    with lanes of state -1 (table entries -inf); rows: where each source's log probabilities start in
    log_probs. Returns the best final state and its log probability."""
    n_s, n_m = len(first_state), len(multi)
    prev = log_initial.copy()
    cur = np.empty(n_s, np.float64)
    best, density = np.empty(n_m, np.float64), np.empty(n_m, np.float64)
    arg = np.empty(n_m, np.int32)
    for frame in range(densities.shape[0]):
        d = densities[frame]
        d0 = d[0]
        for state in range(1, n_s):  # contiguous: vectorised
            p = prev[state - 1] + first_log_prob[state] + d0
            cur[state] = p if p > -np.inf else -np.inf  # madmom keeps -inf unless a path beats it (NaN too)
        for state in irregular:
            p = prev[first_state[state]] + first_log_prob[state] + d[om_pointers[state]]
            cur[state] = p if p > -np.inf else -np.inf
        for m in range(n_m):
            density[m] = d[om_pointers[multi[m]]]
            best[m] = -np.inf  # the first transition then sets what the pass above would (NaN or -inf: -inf)
            arg[m] = first_state[multi[m]]
        for block in range(len(blocks) - 1):
            m0, m1 = blocks[block, 0], blocks[block + 1, 0]
            block_best, block_arg, block_density = best[m0:m1], arg[m0:m1], density[m0:m1]
            for j in range(blocks[block, 1], blocks[block + 1, 1]):
                source, value, row = sources[j], prev[sources[j]], log_probs[rows[j] : rows[j] + m1 - m0]
                for m in range(m1 - m0):  # from 0, so that numba's negative-index handling folds away
                    p = value + row[m] + block_density[m]
                    b = block_best[m]
                    block_best[m] = max(b, p)  # p if p > b else b, as a select: the loop vectorises (not as an if)
                    block_arg[m] = source if p > b else block_arg[m]
        for m in range(n_m):
            if multi[m] >= 0:  # not a padding lane
                cur[multi[m]] = best[m]
            bt[frame, m] = arg[m]
        prev, cur = cur, prev
    state = int(np.argmax(prev))
    return state, prev[state]


@njit(cache=True, nogil=True)
def _backtrack(bt: np.ndarray, first_state: np.ndarray, multi_index: np.ndarray,
               state: int) -> np.ndarray:  # pragma: no cover - compiled
    """The path ending in `state`: a state with one transition came from its first; others from bt."""
    path = np.empty(bt.shape[0], np.uint32)
    for frame in range(bt.shape[0] - 1, -1, -1):
        path[frame] = state
        m = multi_index[state]
        state = first_state[state] if m < 0 else bt[frame, m]
    return path


def _viterbi_numpy(
    densities: np.ndarray, om_pointers: np.ndarray, first_state: np.ndarray, first_log_prob: np.ndarray,
    irregular: np.ndarray, multi: np.ndarray, blocks: np.ndarray, sources: np.ndarray, rows: np.ndarray,
    log_probs: np.ndarray, log_initial: np.ndarray, bt: np.ndarray,
) -> tuple[int, float]:
    """`_viterbi` in numpy, a frame at a time (jit.py: what runs before it is compiled): the same sums in the
    same order, and per multi state the first source of the greatest sum in madmom's order (argmax returns
    the first), so the same path and log probability. A NaN sum never wins there, nor here."""
    n_m = len(multi)
    prev = log_initial.copy()
    cur = np.empty(len(first_state), np.float64)
    first_lp, irregular_first = first_log_prob[1:], first_state[irregular]
    irregular_lp, irregular_om = first_log_prob[irregular], om_pointers[irregular]
    lanes = multi >= 0
    multi_om, multi_first = om_pointers[multi], first_state[multi]  # a padding lane's -1 wraps, as in numba
    # All blocks side by side, one numpy call each per frame instead of one per block: row j of a block's
    # columns is its j-th source, rows past its sources -inf (a sum there never wins: argmax takes the first
    # greatest, and a column of -inf only falls back to the state's first transition, as in the loop).
    n_rows = int(np.diff(blocks[:, 1]).max())
    table = np.full((n_rows, n_m), -np.inf)
    source = np.zeros((n_rows, n_m), np.int64)
    for (m0, j0), (m1, j1) in zip(blocks[:-1], blocks[1:], strict=True):
        table[: j1 - j0, m0:m1] = log_probs[rows[j0] + np.arange(j1 - j0)[:, None] * (m1 - m0) + np.arange(m1 - m0)]
        source[: j1 - j0, m0:m1] = sources[j0:j1, None]
    columns = np.arange(n_m)
    for frame in range(densities.shape[0]):
        d = densities[frame]
        p = prev[:-1] + first_lp + d[0]
        cur[1:] = np.where(p > -np.inf, p, -np.inf)
        p = prev[irregular_first] + irregular_lp + d[irregular_om]
        cur[irregular] = np.where(p > -np.inf, p, -np.inf)
        p = prev[source] + table + d[multi_om]
        p[np.isnan(p)] = -np.inf
        i = np.argmax(p, axis=0)
        best = p[i, columns]
        cur[multi[lanes]] = best[lanes]
        bt[frame] = np.where(best > -np.inf, source[i, columns], multi_first)
        prev, cur = cur, prev
    state = int(np.argmax(prev))
    return state, prev[state]


class CompiledHMM:
    """Drop-in for a madmom HiddenMarkovModel where only `viterbi` is called (as the DBN trackers do)."""

    def __init__(self, hmm) -> None:
        tm = hmm.transition_model
        self.transition_model, self.observation_model = tm, hmm.observation_model
        self.initial_distribution = hmm.initial_distribution
        pointers = np.ascontiguousarray(tm.pointers, np.int64)
        states = np.ascontiguousarray(tm.states, np.int64)
        log_probs = np.ascontiguousarray(tm.log_probabilities, np.float64)
        if np.any(np.diff(pointers) < 1):
            raise TypeError("a state without a transition into it")
        first = states[pointers[:-1]]
        self.om_pointers = np.ascontiguousarray(hmm.observation_model.pointers, np.int64)
        multi = np.flatnonzero(np.diff(pointers) > 1)
        irregular = np.flatnonzero((first != np.arange(len(first)) - 1) | (self.om_pointers != 0))
        irregular = np.setdiff1d(irregular, multi)  # the multi states' own pass gives them their first too
        # multi states that share sources form a block (one per beat of the bar: its first states at every
        # tempo, fed by the previous beat's last states)
        graph = csr_matrix((np.ones(len(states)), (np.repeat(np.arange(len(first)), np.diff(pointers)), states)))
        _, label = connected_components(graph[multi] @ graph[multi].T, directed=False)
        self.multi, blocks, sources, rows, table = [], [[0, 0]], [], [], []
        for block in np.unique(label):
            members = multi[label == block]
            block_sources = np.unique(np.concatenate([states[pointers[m] : pointers[m + 1]] for m in members]))
            dense = np.full((len(block_sources), -(-len(members) // LANES) * LANES), -np.inf)
            for i, m in enumerate(members):
                own = states[pointers[m] : pointers[m + 1]]
                if np.any(np.diff(own) <= 0):
                    raise TypeError("transitions not in ascending order of their source state")
                dense[np.searchsorted(block_sources, own), i] = log_probs[pointers[m] : pointers[m + 1]]
            rows.extend(sum(map(len, table)) + dense.shape[1] * np.arange(len(block_sources)))
            self.multi.extend([*members, *[-1] * (dense.shape[1] - len(members))])
            sources.extend(block_sources)
            table.append(dense.ravel())
            blocks.append([len(self.multi), len(sources)])
        self.multi = np.array(self.multi, np.int64)
        self.multi_index = np.full(tm.num_states, -1, np.int64)
        lanes = np.flatnonzero(self.multi >= 0)
        self.multi_index[self.multi[lanes]] = lanes
        self._tm = (first, log_probs[pointers[:-1]], irregular, self.multi, np.array(blocks, np.int64),
                    np.array(sources, np.int32), np.array(rows, np.int64), np.concatenate([np.zeros(0), *table]))

    def viterbi(self, observations: np.ndarray) -> tuple[np.ndarray, float]:
        """(best state path, its log probability), as madmom's HiddenMarkovModel.viterbi returns them."""
        om = self.observation_model
        densities = np.ascontiguousarray(om.log_densities(observations), np.float64)
        bt = np.empty((len(observations), len(self.multi)), np.int32)
        with np.errstate(divide="ignore"):
            log_initial = np.log(self.initial_distribution)
        viterbi = jit.pick(_viterbi, _viterbi_numpy)
        state, log_prob = viterbi(densities, self.om_pointers, *self._tm, log_initial, bt)
        if np.isinf(log_prob):
            warnings.warn("-inf log probability during Viterbi decoding cannot find a valid path", RuntimeWarning,
                          stacklevel=2)
            return np.empty(0, np.uint32), log_prob
        return jit.pick(_backtrack, _backtrack.py_func)(bt, self._tm[0], self.multi_index, state), log_prob


KERNELS = (_viterbi, _backtrack)  # what jit.pick chooses between, for the warm-up


def load_compiled() -> None:
    """Load the compiled decode (numba's on-disk cache, or a compile) into this process, so that worker
    processes forked from it start with it instead of each loading it again."""
    zero, none, bt = np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros((1, 0), np.int32)
    _viterbi(np.zeros((1, 1)), zero, zero, np.zeros(1), zero, none, np.zeros((1, 2), np.int64),
             np.zeros(0, np.int32), none, np.zeros(0), np.zeros(1), bt)
    _backtrack(bt, zero, np.full(1, -1), 0)


def compiled_dbn(processor):
    """madmom's DBNDownBeatTrackingProcessor (or another tracker holding `hmms`) with each HMM's Viterbi
    decode compiled; everything else is madmom's own object."""
    processor.hmms = [CompiledHMM(h) for h in processor.hmms]
    return processor
