"""Sparsity of the design tangents: which parameters each solved quantity depends on.

A point's position, a link's angle or a joint variable depends on only a few of a machine's
parameters: those of the unit that solves it and, transitively, those its inputs depend on. That
set (the quantity's *support*, sorted parameter indices) is found here once per machine and
selection of program rows, together with the index maps the compiled tangent kernel
(:mod:`sewmech.engine._tangents`) needs to carry compact tangents: per position one flat row
holding, for every solved quantity, its derivatives by its support's parameters only (a point:
x by the support, then y by the support).

Quantities are numbered points first, then links, then joint variables: ``q = point``,
``n_points + link``, ``n_points + n_links + variable``. Every output of a program row shares
the row's support (the union of its own parameters and its inputs' supports).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _kernels as K

#: map slots of a program row (inputs, in the order the kernel reads them)
ROW_SLOTS = 3
#: map slots of a loop term: 0 the point (a TERM_POINT's, a cam's pivot), 1 the length
#: variable, 2 the angle, 3 the cam's link
TERM_SLOTS = 4


@dataclass(frozen=True)
class TangentLayout:
    """Supports and index maps of a program (see the module docstring).

    rows : the program rows (as the kernel takes them, solve order); qoff, qm : per quantity
    the offset of its tangents in a position's flat row and its support's size (0: constant);
    width : the flat row's length; support : per quantity its sorted parameter indices;
    row_out : per row its first output quantity's offset and support size; rin : per row the
    offsets into ``maps`` of its inputs' maps (slots as the row's opcode reads them, -1 none);
    ppos : per row each parameter's place in the row's support (-1: not in it); tin : per loop
    term the map offsets of its inputs (TERM_SLOTS, -1 none); maps : every input's support
    mapped into the support of the row that reads it (flat); max_m : the largest support.
    """

    rows: np.ndarray
    qoff: np.ndarray
    qm: np.ndarray
    width: int
    support: tuple
    row_out: np.ndarray
    rin: np.ndarray
    ppos: np.ndarray
    tin: np.ndarray
    maps: np.ndarray
    max_m: int


def _row_inputs_and_params(machine, row) -> tuple[list, list, list]:
    """(input quantities by slot (None: no input), own parameters, output quantities) of one
    program row, quantities numbered as in the module docstring."""
    n_pt, n_l = len(machine.point_names), len(machine.link_names)

    def p(i):
        return int(i)

    def lk(i):
        return n_pt + int(i)

    def var(i):
        return n_pt + n_l + int(i)

    op = int(row[0])
    if op == K.OP_FIXED:
        return [], [row[2], row[3]], [p(row[1])]
    if op == K.OP_CRANK:
        own = [row[2], row[4] if row[4] >= 0 else row[3]]
        return [], own, [lk(row[1])]
    if op == K.OP_POINT:
        return [p(row[3]), lk(row[2])], [row[4], row[5]], [p(row[1])]
    if op == K.OP_RRR:
        return [p(row[1]), p(row[2])], [row[6], row[7]], [p(row[3]), lk(row[4]), lk(row[5])]
    if op == K.OP_RRP:
        return ([p(row[2]), lk(row[3]), p(row[1])], [row[7], row[8], row[9]],
                [p(row[4]), lk(row[5]), lk(row[6]), var(row[11])])
    if op == K.OP_RPR:
        out = [lk(row[3]), var(row[7])] + ([lk(row[4])] if row[4] >= 0 else [])
        return [p(row[1]), p(row[2])], [row[5]], out
    # a loop group: inputs are per term (see _term_inputs); the outputs are its unknowns
    n, u0 = int(machine.groups[row[1], 0]), int(machine.groups[row[1], 1])
    unk = machine.unknowns
    out = [lk(unk[j, 1]) if unk[j, 0] == 0 else var(unk[j, 1]) for j in range(u0, u0 + n)]
    return [], [], out


def _term_inputs(machine, term) -> tuple[list, list]:
    """(input quantities by TERM_SLOTS, own parameters) of one loop term."""
    n_pt, n_l = len(machine.point_names), len(machine.link_names)
    slots: list = [None] * TERM_SLOTS
    own: list = []
    typ = int(term[0])
    if typ == K.TERM_POINT:
        slots[0] = int(term[4])
        return slots, own
    if typ == K.TERM_VEC:
        if term[3] == K.SRC_PARAM:
            own.append(term[4])
        elif term[10] < 0:
            slots[1] = n_pt + n_l + int(term[4])
    # the angle: a link's or a variable's (a loop's own unknown is no input at the positions,
    # but its position tangent is one at the rates: the group's own support holds it anyway)
    if term[11] < 0:
        slots[2] = (n_pt + int(term[6]) if term[5] == K.SRC_LINK
                    else n_pt + n_l + int(term[6]))
    if term[7] >= 0:
        own.append(term[7])
    if typ == K.TERM_CAM:
        cl, cp, a0, na = (int(x) for x in machine.cams[term[8]])
        slots[0] = cp
        slots[3] = n_pt + cl
        for k in range(a0, a0 + na):
            own += [machine.arcs[k, 0], machine.arcs[k, 1], machine.arcs[k, 2]]
        if term[9] >= 0:
            own.append(term[9])
    return slots, own


def tangent_layout(machine, rows: np.ndarray) -> TangentLayout:
    """The supports and maps of the program rows ``rows`` (indices into ``machine.program``,
    solve order) of ``machine``."""
    n_pt, n_l, n_v = (len(machine.point_names), len(machine.link_names),
                      len(machine.variable_names))
    n_q = n_pt + n_l + n_v
    n_par = len(machine.parameter_names)
    program = machine.program[rows]
    support: list = [()] * n_q
    qoff = np.zeros(n_q, dtype=np.int64)
    qm = np.zeros(n_q, dtype=np.int64)
    row_out = np.zeros((len(program), 2), dtype=np.int64)
    rin = np.full((len(program), ROW_SLOTS), -1, dtype=np.int64)
    ppos = np.full((len(program), n_par), -1, dtype=np.int64)
    tin = np.full((machine.terms.shape[0], TERM_SLOTS), -1, dtype=np.int64)
    maps: list[int] = []
    width = 0

    def mapped(q, place):  # the offset of q's support mapped into a row's (appended)
        start = len(maps)
        maps.extend(place[j] for j in support[q])
        return start

    for r, row in enumerate(program):
        inputs, own, outputs = _row_inputs_and_params(machine, row)
        terms = []
        if int(row[0]) == K.OP_LOOP:
            _, _, _, t0, nt = (int(x) for x in machine.groups[row[1]])
            terms = [(t, *_term_inputs(machine, machine.terms[t])) for t in range(t0, t0 + nt)]
        sup = {int(j) for j in own if j >= 0}
        for q in inputs:
            sup |= set(support[q])
        for _, slots, town in terms:
            sup |= {int(j) for j in town if j >= 0}
            for q in slots:
                if q is not None:
                    sup |= set(support[q])
        sup = tuple(sorted(sup))
        place = {j: k for k, j in enumerate(sup)}
        ppos[r, list(sup)] = np.arange(len(sup))
        for s, q in enumerate(inputs):
            rin[r, s] = mapped(q, place)
        for t, slots, _ in terms:
            for s, q in enumerate(slots):
                if q is not None:
                    tin[t, s] = mapped(q, place)
        m = len(sup)
        row_out[r] = (width, m)
        for q in outputs:
            support[q] = sup
            qoff[q] = width
            qm[q] = m
            width += 2 * m if q < n_pt else m
    maps_a = np.asarray(maps, dtype=np.int64)
    arrays = [rows, qoff, qm, row_out, rin, ppos, tin, maps_a]
    for a in arrays:
        a.setflags(write=False)
    return TangentLayout(np.asarray(rows, dtype=np.int64), qoff, qm, width, tuple(support),
                         row_out, rin, ppos, tin, maps_a, max(qm.max(initial=0), 1))
