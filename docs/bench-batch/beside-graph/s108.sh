#!/bin/bash
# session 106: the worlds' refreshes beside the step's first graph, a batch A/B against 731d2f7, then the host's parts (h107.py)
export PYTHONUNBUFFERED=1
rm -rf $HOME/n108 $HOME/o106 $HOME/bb && mkdir -p $HOME/n108 $HOME/o106 $HOME/bb && cp -r warpsoft kernels tools scenes pyproject.toml .devpack/h107.py $HOME/n108/ && ln -sfn ../kernels $HOME/n108/warpsoft/kernels
tar xzf .devpack/old106.tar.gz -C $HOME/o106 && ln -sfn ../kernels $HOME/o106/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u108.log; nproc >> $R/u108.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --steps 100 --out $HOME/bb/$1 $3 2>&1 | tee $HOME/bb/full108_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u108.log); cp $HOME/bb/$1/batch.json $R/bb108_$1.json; python3 -c "import json;r=json.load(open('$R/bb108_$1.json'))['rows'][0];print('$1', 'mean', round(r['step_mean_ms'],2), 'median', round(r['step_ms'],2), 'graph', round(r['graph_ms'],2), 'refresh', round(r['refresh_ms'],2), 'run/s', round(r['run_design_steps_per_s']))" >> $R/u108.log; echo "bb $1 done" >> $R/u108.log; }
bb new0 $HOME/n108
bb old0 $HOME/o106
bb new1 $HOME/n108
bb old1 $HOME/o106
(cd $HOME/n108 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n108 timeout 900 python3 h107.py > $R/h108.log 2>&1)
echo "all done" >> $R/u108.log
