#!/bin/bash
# session 72, last: bench.py one robot, this tree against 5146b6a, alternated twice; then the panels' operand
# rows indexed or read whole
export PYTHONUNBUFFERED=1
rm -rf $HOME/n75 $HOME/o75 $HOME/devmesh && mkdir -p $HOME/n75 $HOME/o75 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n75/ && ln -sfn ../kernels $HOME/n75/warpsoft/kernels
tar xzf .devpack/old72.tar.gz -C $HOME/o75 && ln -sfn ../kernels $HOME/o75/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | sed "s/^/$1 /" >> $R/u75.log); }
b new0 $HOME/n75; b old0 $HOME/o75; b new1 $HOME/n75; b old1 $HOME/o75
echo "robots done" >> $R/u75.log
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
(cd $HOME/n75 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n75 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --loads indexed whole --out $R/levels75.json 2>&1 | sed "s/^/levels /" >> $R/u75.log)
echo "all done" >> $R/u75.log
