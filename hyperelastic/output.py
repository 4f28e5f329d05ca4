"""HDF5 output (rank 0 writes, flushed every frame) and an XDMF time series beside it.

Layout: mesh/points (nv,3), mesh/tetra (nc,4) in the input mesh's numbering; time (F,);
x (F,nv,3) positions in the input vertex order; stats/<column> (S,) one entry per step;
attributes: options (the full options database), scene, effects, effects_built, versions, ranks.
"""
import os

import numpy as np

from .errors import UserError


def check_output_path(path):
    """Raise UserError unless `path` can be written (checked before any work is done)."""
    if os.path.isdir(path):
        raise UserError(f"output '{path}' is a directory")
    d = os.path.dirname(os.path.abspath(path)) or "."
    if not os.path.isdir(d):
        try:
            os.makedirs(d, exist_ok=True)
        except OSError as e:
            raise UserError(f"output '{path}': cannot create directory '{d}' ({e.strerror})") from None
    if not os.access(d, os.W_OK) or (os.path.exists(path) and not os.access(path, os.W_OK)):
        raise UserError(f"output '{path}': not writable")


class Writer:
    def __init__(self, path, space, points, tets, attrs):
        self.space = space
        self.root = space.mpi.rank == 0
        self.path = path
        self.xdmf = os.path.splitext(path)[0] + ".xdmf"
        self.nframes = 0
        self.nstats = 0
        if not self.root:
            return
        import h5py
        self.f = f = h5py.File(path, "w")
        nv = len(points)
        f.create_dataset("mesh/points", data=np.asarray(points, np.float64))
        f.create_dataset("mesh/tetra", data=np.asarray(tets, np.int64))
        f.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(256,))
        f.create_dataset("x", shape=(0, nv, 3), maxshape=(None, nv, 3), dtype=np.float64, chunks=(1, nv, 3))
        f.create_group("stats")
        for k, v in attrs.items():
            f.attrs[k] = v
        f.flush()
        self.nv, self.nc = nv, len(tets)

    def frame(self, t, x_local):
        full = self.space.gather(x_local)
        if not self.root:
            return
        f = self.f
        i = self.nframes
        f["time"].resize((i + 1,))
        f["x"].resize((i + 1, self.nv, 3))
        f["x"][i] = full
        f["time"][i] = t
        self.nframes += 1
        f.flush()
        self._write_xdmf()

    def stats(self, row):
        if not self.root:
            return
        g = self.f["stats"]
        i = self.nstats
        for k, v in row.items():
            if k not in g:
                is_int = isinstance(v, (int, np.integer))
                g.create_dataset(k, shape=(i,), maxshape=(None,), chunks=(256,),
                                 dtype=np.int64 if is_int else np.float64, fillvalue=0 if is_int else np.nan)
        for k in g:                      # every column has one entry per step (missing: NaN / 0)
            g[k].resize((i + 1,))
            if k in row:
                g[k][i] = row[k]
        self.nstats += 1

    def set_attr(self, key, value):
        if self.root:
            self.f.attrs[key] = value

    def close(self):
        if self.root and getattr(self, "f", None) is not None:
            self.f.flush()
            self.f.close()
            self.f = None

    def _write_xdmf(self):
        h5 = os.path.basename(self.path)
        times = self.f["time"][:]
        nv, nc, nf = self.nv, self.nc, self.nframes
        grids = []
        for i, t in enumerate(times):
            grids.append(f"""   <Grid Name="frame{i}" GridType="Uniform">
    <Time Value="{t:.17g}"/>
    <Topology TopologyType="Tetrahedron" NumberOfElements="{nc}">
     <DataItem Dimensions="{nc} 4" NumberType="Int" Precision="8" Format="HDF">{h5}:/mesh/tetra</DataItem>
    </Topology>
    <Geometry GeometryType="XYZ">
     <DataItem ItemType="HyperSlab" Dimensions="1 {nv} 3" Type="HyperSlab">
      <DataItem Dimensions="3 3" Format="XML">{i} 0 0 1 1 1 1 {nv} 3</DataItem>
      <DataItem Dimensions="{nf} {nv} 3" NumberType="Float" Precision="8" Format="HDF">{h5}:/x</DataItem>
     </DataItem>
    </Geometry>
   </Grid>""")
        text = ('<?xml version="1.0" ?>\n<Xdmf Version="3.0">\n <Domain>\n'
                '  <Grid Name="hyperelastic" GridType="Collection" CollectionType="Temporal">\n'
                + "\n".join(grids) + "\n  </Grid>\n </Domain>\n</Xdmf>\n")
        tmp = self.xdmf + ".tmp"
        with open(tmp, "w") as fh:
            fh.write(text)
        os.replace(tmp, self.xdmf)
