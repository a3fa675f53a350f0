"""Reading a Wavefront OBJ's vertices and triangles (polygons fanned, indices
0-based, negative ones counted from the end) for the scripts beside this one.
Plain Python: it runs in Blender's interpreter too."""


class ObjError(Exception):
    """A file that cannot be read as a triangle mesh; the message names the file (and the line)."""


def read_obj(path):
    verts, tris = [], []
    try:
        f = open(path)
    except OSError as e:
        raise ObjError(f"{path}: {e.strerror}")
    with f:
        for number, line in enumerate(f, 1):
            parts = line.split()
            if not parts:
                continue
            try:
                if parts[0] == "v":
                    verts.append(tuple(float(x) for x in parts[1:4]))
                elif parts[0] == "f":
                    idx = []
                    for token in parts[1:]:
                        i = int(token.split("/")[0])
                        idx.append(i - 1 if i > 0 else len(verts) + i)
                    for k in range(1, len(idx) - 1):
                        tris.append((idx[0], idx[k], idx[k + 1]))
            except ValueError:
                raise ObjError(f"{path}:{number}: cannot read '{line.strip()}'")
    for t in tris:
        if any(i < 0 or i >= len(verts) for i in t):
            raise ObjError(f"{path}: a face refers to a vertex that does not exist ({len(verts)} vertices)")
    if not tris:
        raise ObjError(f"{path}: no faces")
    return verts, tris
