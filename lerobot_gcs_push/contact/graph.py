"""The mode graph as data: a layered DAG of sticking face-contact modes joined by non-collision modes.

Layer l holds one contact vertex per face; a non-collision vertex joins contact (l, i) to contact
(l + 1, j) along one route of free-space pieces, and the start's non-collision vertices join the
finger's start (in any piece it lies in) to layer 0. Every contact vertex may end the plan. Layering,
rather than one contact vertex per face with free subgraphs between them, is what keeps the relaxation
tight: the graph has no cycles, so no flow can circulate through idle copies at zero cost, and each
non-collision vertex has exactly one predecessor and one successor, so its perspective copy is its edges'.
"""

from __future__ import annotations

from dataclasses import dataclass

from lerobot_gcs_push.contact.model import PushModel
from lerobot_gcs_push.contact.non_collision import routes

START = -1  # the layer of the start's non-collision vertices


@dataclass(frozen=True)
class ContactVertex:
    layer: int
    face: int
    piece: int = 0  # which of the face's `pieces` equal intervals of lam the finger sticks in

    @property
    def name(self) -> str:
        return f"contact:{self.face}"


@dataclass(frozen=True)
class FreeVertex:
    layer: int  # START, or the layer of the contact vertex it leaves
    source: int  # the face it leaves, or for START the free-space piece the finger starts in
    target: int  # the face of the next layer's contact vertex
    route: tuple[int, ...]
    source_piece: int = 0
    target_piece: int = 0

    @property
    def name(self) -> str:
        return "free:" + "-".join(map(str, self.route))


@dataclass(frozen=True)
class ContactGraph:
    layers: int
    n_faces: int
    pieces: int
    contacts: tuple[ContactVertex, ...]
    frees: tuple[FreeVertex, ...]

    def contact_index(self, layer: int, face: int, piece: int = 0) -> int:
        return (layer * self.n_faces + face) * self.pieces + piece

    def into(self, c: int) -> list[int]:
        v = self.contacts[c]
        return [
            k
            for k, f in enumerate(self.frees)
            if f.layer == v.layer - 1 and f.target == v.face and f.target_piece == v.piece
        ]

    def out_of(self, c: int) -> list[int]:
        v = self.contacts[c]
        return [
            k
            for k, f in enumerate(self.frees)
            if f.layer == v.layer and f.source == v.face and f.source_piece == v.piece
        ]

    def successor(self, f: int) -> int:
        v = self.frees[f]
        return self.contact_index(v.layer + 1, v.target, v.target_piece)

    def predecessor(self, f: int) -> int | None:
        v = self.frees[f]
        return None if v.layer == START else self.contact_index(v.layer, v.source, v.source_piece)

    def starts(self) -> list[int]:
        return [k for k, f in enumerate(self.frees) if f.layer == START]


def build_graph(model: PushModel, layers: int, pieces: int = 1) -> ContactGraph:
    """`pieces` > 1 splits each face's contact location into equal intervals, one contact vertex each:
    inside one vertex the relaxation mixes contact points from the interval's two ends (the torque arm
    lam * fn is where its slack sits), so narrower intervals leave it less room."""
    nf = len(model.faces)
    contacts = tuple(ContactVertex(layer, j, k) for layer in range(layers) for j in range(nf) for k in range(pieces))
    frees = []
    for layer in range(START, layers - 1):
        for i in range(nf):
            for ki in range(1 if layer == START else pieces):
                for j in range(nf):
                    for r in routes(nf, i, j):
                        for kj in range(pieces):
                            frees.append(FreeVertex(layer, i, j, r, ki, kj))
    return ContactGraph(layers, nf, pieces, contacts, tuple(frees))
