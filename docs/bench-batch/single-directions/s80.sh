#!/bin/bash
# session 78, second machine: the assembled product as sliced ELLPACK (prod80.py)
export PYTHONUNBUFFERED=1
rm -rf $HOME/n80 && mkdir -p $HOME/n80 && cp -r warpsoft kernels tools scenes pyproject.toml .devpack $HOME/n80/ && ln -sfn ../kernels $HOME/n80/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u80.log
(cd $HOME/n80 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n80 timeout 600 python3 .devpack/prod80.py 1024 $R/prod80.json cuda 2>&1 | grep -v "^Module" | sed "s/^/prod /" >> $R/u80.log)
echo "prod done" >> $R/u80.log
