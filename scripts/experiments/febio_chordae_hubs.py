#!/usr/bin/python3
"""Experiment (docs/febio-export.md, "Chordae on a hub"): rewrite an exported valve.feb so that
each chorda pulls its cross-section's mean point, as mvtwin's chorda does, instead of one spring
per cross-section node.

    scripts/experiments/febio_chordae_hubs.py IN.feb OUT.feb

Each chorda C's springs chorda_C_1..k (node -> papillary tip, force share 1/k each) become one
spring chorda_C_1 (share 1, the same force curve, which already reads the mean point's
elongation) from a new hub node at the mean of the k nodes to the tip, and the hub is tied to
the mean of the nodes by FEBio linear constraints (<bc type="linear constraint">: hub dof =
sum of the nodes' dofs / k, for x, y and z): the chorda's pull reaches each node as 1/k of it
whatever the cross-section does. Standard library only.
"""
import re
import sys


def main(src, dst):
    t = open(src).read()
    nodes = {int(m.group(1)): tuple(map(float, m.group(2).split(",")))
             for m in re.finditer(r'<node id="(\d+)">([^<]+)</node>', t)}
    sets = re.findall(r'( *)<DiscreteSet name="(chorda_(\d+)_(\d+))">\s*<delem>(\d+),(\d+)</delem>'
                      r'\s*</DiscreteSet>\n', t)
    chords = {}
    for _, name, c, _, a, b in sets:
        chords.setdefault(int(c), []).append((name, int(a), int(b)))
    if not chords:
        sys.exit("no chorda springs (DiscreteSet chorda_C_J) in " + src)
    hub, xml = {}, '    <Nodes name="chordae_hubs">\n'
    for k, c in enumerate(sorted(chords)):
        hub[c] = max(nodes) + 1 + k
        pts = [nodes[a] for _, a, _ in chords[c]]
        m = [sum(p[i] for p in pts) / len(pts) for i in range(3)]
        xml += '      <node id="%d">%.12g,%.12g,%.12g</node>\n' % (hub[c], *m)
    xml += "    </Nodes>\n"
    i = t.index('<Nodes name="papillary_tips">')
    j = t.index("</Nodes>\n", i) + len("</Nodes>\n")
    t = t[:j] + xml + t[j:]
    for c, springs in chords.items():
        for idx, (name, a, b) in enumerate(springs):
            old = re.search(r' *<DiscreteSet name="%s">\s*<delem>%d,%d</delem>\s*</DiscreteSet>\n'
                            % (name, a, b), t).group(0)
            new = ('    <DiscreteSet name="%s">\n      <delem>%d,%d</delem>\n    </DiscreteSet>\n'
                   % (name, hub[c], b)) if idx == 0 else ""
            t = t.replace(old, new, 1)
            mat = re.search(r' *<discrete_material id="(\d+)" name="%s" type="nonlinear spring">'
                            r'.*?</discrete_material>\n' % name, t, re.S)
            if idx == 0:
                t = t.replace(mat.group(0),
                              re.sub(r"<scale>[^<]+</scale>", "<scale>1</scale>", mat.group(0)), 1)
            else:
                t = t.replace(mat.group(0), "", 1)
                t = re.sub(r' *<discrete dmat="%s" discrete_set="%s"/>\n' % (mat.group(1), name),
                           "", t, count=1)
    ids = {}

    def renumber(m):
        ids[m.group(1)] = str(len(ids) + 1)
        return '<discrete_material id="%s"' % ids[m.group(1)]
    t = re.sub(r'<discrete_material id="(\d+)"', renumber, t)
    t = re.sub(r'<discrete dmat="(\d+)"', lambda m: '<discrete dmat="%s"' % ids[m.group(1)], t)
    bcs = ""
    for c, springs in chords.items():
        for d in "xyz":
            bcs += ('    <bc type="linear constraint">\n      <node>%d</node>\n      <dof>%s</dof>\n'
                    % (hub[c], d))
            for _, a, _ in springs:
                bcs += ("      <child_dof>\n        <node>%d</node>\n        <dof>%s</dof>\n"
                        "        <value>%.17g</value>\n      </child_dof>\n" % (a, d, 1.0 / len(springs)))
            bcs += "    </bc>\n"
    t = t.replace("  </Boundary>", bcs + "  </Boundary>", 1)
    open(dst, "w").write(t)
    print("%d chordae on hubs (%d springs before)" % (len(chords), sum(map(len, chords.values()))))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
