#!/bin/bash
# session 59: bench_levels, the short rows' lanes at full load and in the tail
export PYTHONUNBUFFERED=1
rm -rf $HOME/n59 && mkdir -p $HOME/n59 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n59/ && ln -sfn ../kernels $HOME/n59/warpsoft/kernels
rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u59.log
(cd $HOME/n59 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n59 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --short-lanes 1 2 4 --tail-lanes 1 4 8 32 32,16,4 --out $R/levels59.json 2>&1 | sed "s/^/levels /" >> $R/u59.log)
echo "s59 done" >> $R/u59.log
