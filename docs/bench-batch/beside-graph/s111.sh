#!/bin/bash
# session 106: the final tree (refreshes beside the first graph, values staged, reads on the step's stream, an iteration's
# records beside the next graph) against 731d2f7 on one machine
export PYTHONUNBUFFERED=1
rm -rf $HOME/n111 $HOME/o106 $HOME/bb && mkdir -p $HOME/n111 $HOME/o106 $HOME/bb && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n111/ && ln -sfn ../kernels $HOME/n111/warpsoft/kernels
tar xzf .devpack/old106.tar.gz -C $HOME/o106 && ln -sfn ../kernels $HOME/o106/warpsoft/kernels
R=$HOME/res; mkdir -p $R
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u111.log; nproc >> $R/u111.log
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --steps 100 --out $HOME/bb/$1 $3 2>&1 | tee $HOME/bb/full111_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u111.log); cp $HOME/bb/$1/batch.json $R/bb111_$1.json; python3 -c "import json;r=json.load(open('$R/bb111_$1.json'))['rows'][0];print('$1', 'mean', round(r['step_mean_ms'],2), 'median', round(r['step_ms'],2), 'graph', round(r['graph_ms'],2), 'refresh', round(r['refresh_ms'],2), 'run/s', round(r['run_design_steps_per_s']), 'cg', sum(r['step_cg_iterations']), 'refreshes', r['world_refreshes'])" >> $R/u111.log; echo "bb $1 done" >> $R/u111.log; }
bb fin0 $HOME/n111
bb old0 $HOME/o106
echo "all done" >> $R/u111.log
