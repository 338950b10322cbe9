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

    @property
    def name(self) -> str:
        return f"contact:{self.face}"


@dataclass(frozen=True)
class FreeVertex:
    layer: int  # START, or the layer of the contact vertex it leaves
    source: int  # the face it leaves, or for START the free-space piece the finger starts in
    target: int  # the face of the next layer's contact vertex
    route: tuple[int, ...]

    @property
    def name(self) -> str:
        return "free:" + "-".join(map(str, self.route))


@dataclass(frozen=True)
class ContactGraph:
    layers: int
    contacts: tuple[ContactVertex, ...]
    frees: tuple[FreeVertex, ...]

    def contact_index(self, layer: int, face: int) -> int:
        return layer * self.n_faces + face

    @property
    def n_faces(self) -> int:
        return len(self.contacts) // self.layers

    def into(self, c: int) -> list[int]:
        v = self.contacts[c]
        return [k for k, f in enumerate(self.frees) if f.layer == v.layer - 1 and f.target == v.face]

    def out_of(self, c: int) -> list[int]:
        v = self.contacts[c]
        return [k for k, f in enumerate(self.frees) if f.layer == v.layer and f.source == v.face]

    def successor(self, f: int) -> int:
        v = self.frees[f]
        return self.contact_index(v.layer + 1, v.target)

    def predecessor(self, f: int) -> int | None:
        v = self.frees[f]
        return None if v.layer == START else self.contact_index(v.layer, v.source)

    def starts(self) -> list[int]:
        return [k for k, f in enumerate(self.frees) if f.layer == START]


def build_graph(model: PushModel, layers: int) -> ContactGraph:
    nf = len(model.faces)
    contacts = tuple(ContactVertex(layer, j) for layer in range(layers) for j in range(nf))
    frees = []
    for layer in range(START, layers - 1):
        for i in range(nf):
            for j in range(nf):
                for r in routes(nf, i, j):
                    frees.append(FreeVertex(layer, i, j, r))
    return ContactGraph(layers, contacts, tuple(frees))
