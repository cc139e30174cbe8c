#!/bin/bash
cd /work/main
V=/work/main/.venv/bin/python
for r in 0 1; do
 for t in new old; do
  if [ $t = new ]; then D=/work/main; else D=/tmp/c/old; fi
  (cd $D && WARPSOFT_MESH_CACHE=/work/main/.devmesh PYTHONPATH=$D $V tools/bench.py --device cpu --steps 30 --warmup 5 --scenes finger diamond_inverse --out /tmp/c/b_$t$r 2>&1 | grep -E "median" | grep -v "^|" | sed "s/^/$t$r /")
  (cd $D && WARPSOFT_MESH_CACHE=/work/main/.devmesh1024 PYTHONPATH=$D $V tools/batch_bench.py --device cpu --sizes 4 --meshes 4 --steps 10 --warmup 3 --solver pcg --preconditioner factors --share-tolerance 0.01 --out /tmp/c/bb_$t$r 2>&1 | grep "batch " | sed "s/^/$t$r /")
 done
done
echo AB DONE
