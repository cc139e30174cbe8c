#!/bin/bash
# session 58: one robot (bench.py, cuda) at HEAD against c26ab95, alternated twice
export PYTHONUNBUFFERED=1
rm -rf $HOME/n58 $HOME/o58 && mkdir -p $HOME/n58 $HOME/o58 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n58/ && ln -sfn ../kernels $HOME/n58/warpsoft/kernels
tar xzf .devpack/old57.tar.gz -C $HOME/o58 && ln -sfn ../kernels $HOME/o58/warpsoft/kernels
rm -rf $HOME/devmesh && cp -r .devmesh $HOME/devmesh && rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
rb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse --out $R/rb58_$1 2>&1 | grep -E "^\| (finger|diamond_inverse) " | sed "s/^/$1 /" >> $R/u58.log); }
rb new0 $HOME/n58; rb old0 $HOME/o58; rb new1 $HOME/n58; rb old1 $HOME/o58
echo "s58 done" >> $R/u58.log
