#!/bin/bash
# session 58: one robot (bench.py, cuda) at HEAD against c26ab95, alternated twice
export PYTHONUNBUFFERED=1
rm -rf $HOME/n58 $HOME/o58 && mkdir -p $HOME/n58 $HOME/o58 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n58/ && ln -sfn ../kernels $HOME/n58/warpsoft/kernels
tar xzf .devpack/old57.tar.gz -C $HOME/o58 && ln -sfn ../kernels $HOME/o58/warpsoft/kernels
rm -rf $HOME/devmesh && cp -r .devmesh $HOME/devmesh && rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
mkdir -p $HOME/res
export PYTHONUNBUFFERED=1
R=$HOME/res
for r in 0 1; do for t in n58 o58; do (cd $HOME/$t && for s in diamond_inverse finger; do WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$HOME/$t timeout 300 python3 $HOME/devpack/share58.py $s cuda 2>&1 | tail -1 | sed "s/^/$t /" >> $R/h58.log; WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$HOME/$t timeout 300 python3 $HOME/devpack/host58.py $HOME/$t $s cuda 2>&1 | tail -1 >> $R/h58.log; done); done; done
echo "h58 done" >> $R/h58.log
rb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse --out $R/rb59_$1 2>&1 | grep -E "^\| (finger|diamond_inverse) " | sed "s/^/$1 /" >> $R/u59.log); }
rb new0 $HOME/n58; rb old0 $HOME/o58; rb new1 $HOME/n58; rb old1 $HOME/o58
echo "s59 done" >> $R/u59.log
