#!/bin/bash
# session 66: bench.py, one robot, new tree against 1c1e402, alternated twice
export PYTHONUNBUFFERED=1
rm -rf $HOME/n66 $HOME/o66 $HOME/devmesh && mkdir -p $HOME/n66 $HOME/o66 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n66/ && ln -sfn ../kernels $HOME/n66/warpsoft/kernels
tar xzf .devpack/old63.tar.gz -C $HOME/o66 && ln -sfn ../kernels $HOME/o66/warpsoft/kernels
cp -r .devmesh $HOME/devmesh; rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | sed "s/^/$1 /" >> $R/u66.log); }
b new0 $HOME/n66; b old0 $HOME/o66; b new1 $HOME/n66; b old1 $HOME/o66
echo "s66 done" >> $R/u66.log
