#!/bin/bash
export PYTHONUNBUFFERED=1
rm -rf $HOME/n99 && mkdir -p $HOME/n99 && cp -r warpsoft kernels tools scenes pyproject.toml .devpack $HOME/n99/ && ln -sfn ../kernels $HOME/n99/warpsoft/kernels
R=$HOME/res; mkdir -p $R
(cd $HOME/n99 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n99 timeout 1200 python3 .devpack/kern99.py > $R/kern99.log 2>&1)
echo "kern done" >> $R/u99.log
