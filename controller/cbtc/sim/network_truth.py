"""Truth on a track network: two trains whose true spans overlap on a section, or that stand on one switch or crossing
(any part of the piece: its legs or tracks foul each other), have collided, whoever moved."""


def collisions(graph, spans):
    """[(train, train, section, section)] of every pair of trains in collision; `spans` maps train -> ((section, lo_m,
    hi_m), ...), their true extents."""
    found = []
    names = sorted(spans)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            for sa, lo_a, hi_a in spans[a]:
                for sb, lo_b, hi_b in spans[b]:
                    piece = graph.sections[sa].piece
                    if (sa == sb and lo_a < hi_b and lo_b < hi_a) or (piece and piece == graph.sections[sb].piece):
                        found.append((a, b, sa, sb))
    return found
