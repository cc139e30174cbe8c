#!/bin/bash
# session 72, last: whole steps, this tree (panels read operand rows whole) against 8db1cc8
export PYTHONUNBUFFERED=1
rm -rf $HOME/n77 && mkdir -p $HOME/n77 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n77/ && ln -sfn ../kernels $HOME/n77/warpsoft/kernels
R=$HOME/res
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb77_$1 $3 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u77.log); }
bb new $HOME/n77 ""
echo "bb new done" >> $R/u77.log
bb old $HOME/o74 ""
echo "all done" >> $R/u77.log
