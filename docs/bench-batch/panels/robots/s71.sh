#!/bin/bash
# session 67, fifth run: bench.py, one robot, the panels tree against 87cfd9c, alternated twice
export PYTHONUNBUFFERED=1
rm -rf $HOME/n71 $HOME/o71 $HOME/devmesh && mkdir -p $HOME/n71 $HOME/o71 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n71/ && ln -sfn ../kernels $HOME/n71/warpsoft/kernels
tar xzf .devpack/old67.tar.gz -C $HOME/o71 && ln -sfn ../kernels $HOME/o71/warpsoft/kernels
cp -r .devmesh $HOME/devmesh; rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | sed "s/^/$1 /" >> $R/u71.log); }
b new0 $HOME/n71; b old0 $HOME/o71; b new1 $HOME/n71; b old1 $HOME/o71
echo "s71 done" >> $R/u71.log
