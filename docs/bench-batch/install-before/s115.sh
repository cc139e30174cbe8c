#!/bin/bash
# session 114: installs before the first graph again, their values staged beside the last step's graphs, the element blocks made before it; check, then
# 1024 Diamonds alternated with 3c8b83e, then the robots
export PYTHONUNBUFFERED=1
D=$(pwd); cp .devpack/h112.py $HOME/h112.py
rm -rf $HOME/n115 $HOME/o112 $HOME/bb $HOME/devmesh && mkdir -p $HOME/n115 $HOME/o112 $HOME/bb && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n115/ && ln -sfn ../kernels $HOME/n115/warpsoft/kernels
tar xzf .devpack/old112.tar.gz -C $HOME/o112 && ln -sfn ../kernels $HOME/o112/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u115.log; nproc >> $R/u115.log
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done

bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --steps 100 --out $HOME/bb/$1 $3 2>&1 | tee $HOME/bb/full115_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u115.log); cp $HOME/bb/$1/batch.json $R/bb115_$1.json; python3 -c "import json;r=json.load(open('$R/bb115_$1.json'))['rows'][0];print('$1', 'mean', round(r['step_mean_ms'],2), 'median', round(r['step_ms'],2), 'graph', round(r['graph_ms'],2), 'refresh', round(r['refresh_ms'],2), 'install', round(r.get('install_ms',0),2), 'run/s', round(r['run_design_steps_per_s']), 'cg', sum(r['step_cg_iterations']), 'refreshes', r['world_refreshes'], 'staged', r.get('refactor_staged'))" >> $R/u115.log; echo "bb $1 done" >> $R/u115.log; }
bb new0 $HOME/n115
bb old0 $HOME/o112



echo "batches done" >> $R/u115.log
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 100 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | grep -v "^|" | sed "s/^/$1 /" >> $R/u115.log); }
for i in 0 1; do b new$i $HOME/n115; b old$i $HOME/o112; done
echo "all done" >> $R/u115.log
