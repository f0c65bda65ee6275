# time_vs_error.gp — written by report_cull; run from its own folder:
#   cd docs/report && gnuplot time_vs_error.gp
# draws time_vs_error.svg and time_vs_error.png (the same figure).
$city << EOD
# time_us rate_pct threads label
12.415 97.135 1 "spheres"
26.527 97.135 2 "spheres"
13.096 97.131 1 "+AABB"
27.721 97.131 2 "+AABB"
31.325 97.133 1 ">=1px"
45.780 97.133 2 ">=1px"
32.401 96.976 1 ">=2px"
45.956 96.976 2 ">=2px"
31.423 96.647 1 ">=4px"
43.047 96.647 2 ">=4px"
137.480 66.929 1 "occ 128x64"
145.400 66.929 2 "occ 128x64"
172.388 41.305 1 "occ 256x114"
165.123 41.305 2 "occ 256x114"
190.851 23.400 1 "occ 512x256"
198.290 23.400 2 "occ 512x256"
334.374 15.402 1 "occ 1280x720"
368.336 15.402 2 "occ 1280x720"
10.814 41.305 1 "occ 256x114 kept"
19.107 41.305 2 "occ 256x114 kept"
11.095 15.402 1 "occ 1280x720 kept"
15.875 15.402 2 "occ 1280x720 kept"
EOD
$city_labels << EOD
# label_x label_y text point_x point_y moved
13.4603 102.188 "spheres" 12.415 97.135 1
14.1980 98.815 "+AABB" 13.096 97.131 0
33.9605 102.186 ">=1px" 31.325 97.133 1
35.1270 85.185 ">=2px" 32.401 96.976 1
34.0673 91.594 ">=4px" 31.423 96.647 1
149.0485 71.982 "occ 128x64" 137.480 66.929 1
186.8951 42.989 "occ 256x114" 172.388 41.305 0
206.9107 28.453 "occ 512x256" 190.851 23.400 1
362.5118 20.455 "occ 1280x720" 334.374 15.402 1
11.7240 46.358 "occ 256x114 kept" 10.814 41.305 1
12.0287 20.455 "occ 1280x720 kept" 11.095 15.402 1
EOD
$city_front << EOD
10.814 41.305
11.095 15.402
12891.8 15.402
EOD
$rnd << EOD
# time_us rate_pct threads label
8.431 87.389 1 "spheres"
19.342 87.389 2 "spheres"
8.680 87.350 1 "+AABB"
19.386 87.350 2 "+AABB"
22.126 87.109 1 ">=1px"
31.552 87.109 2 ">=1px"
22.394 86.764 1 ">=2px"
30.864 86.764 2 ">=2px"
22.464 86.311 1 ">=4px"
31.876 86.311 2 ">=4px"
159.510 32.496 1 "occ 128x64"
145.620 32.496 2 "occ 128x64"
164.708 20.092 1 "occ 256x114"
149.901 20.092 2 "occ 256x114"
191.322 11.999 1 "occ 512x256"
184.837 11.999 2 "occ 512x256"
344.647 7.361 1 "occ 1280x720"
346.168 7.361 2 "occ 1280x720"
11.919 20.092 1 "occ 256x114 kept"
19.561 20.092 2 "occ 256x114 kept"
12.035 7.361 1 "occ 1280x720 kept"
18.294 7.361 2 "occ 1280x720 kept"
EOD
$rnd_labels << EOD
# label_x label_y text point_x point_y moved
9.1410 92.442 "spheres" 8.431 87.389 1
9.4102 89.034 "+AABB" 8.680 87.350 0
23.9879 92.162 ">=1px" 22.126 87.109 1
24.2781 81.711 ">=2px" 22.394 86.764 1
24.3545 77.889 ">=4px" 22.464 86.311 1
172.9323 34.180 "occ 128x64" 159.510 32.496 0
178.5685 21.777 "occ 256x114" 164.708 20.092 0
207.4215 13.684 "occ 512x256" 191.322 11.999 0
373.6493 9.046 "occ 1280x720" 344.647 7.361 0
12.9218 25.145 "occ 256x114 kept" 11.919 20.092 1
13.0481 12.415 "occ 1280x720 kept" 12.035 7.361 1
EOD
$rnd_front << EOD
8.431 87.389
8.680 87.350
11.919 20.092
12.035 7.361
12891.8 7.361
EOD
set encoding utf8
set logscale x
set xrange [5.90205:1289.18]
set yrange [0:105]
set grid xtics mxtics ytics lc rgb '#dddddd'
set xlabel 'time per query, µs (median; log scale)'
set ylabel 'false-visible rate, % of reported entities'
set key top right box opaque
do for [term = 1:2] {
  if (term == 1) { set terminal svg size 1500,650 dynamic font 'DejaVu Sans,12' background '#ffffff'; set output 'time_vs_error.svg'; psz = 1.0 }
  if (term == 2) { set terminal pngcairo size 1500,650 font 'DejaVu Sans,10' background '#ffffff'; set output 'time_vs_error.png'; psz = 1.3 }
  set multiplot layout 1,2 title "Culling: time per query against false-visible rate (truth: exact frustum + 1920x1080 ray caster)\n{/*0.8 machine: 2 cpus, Intel(R) Xeon(R) Processor; 2026-11-27}"
  set title 'city scene walk'
  plot $city_front using 1:2 with steps lw 2 lc rgb '#2ca02c' title 'Pareto front', \
       $city_labels using 1:2:($4 - $1):($6 > 0 ? $5 - $2 : 1/0) with vectors nohead lc rgb '#aaaaaa' notitle, \
       $city using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps psz lc rgb '#1f77b4' title '1 thread', \
       $city using 1:($3 == 2 ? $2 : 1/0) with points pt 9 ps psz * 1.15 lc rgb '#d62728' title '2 threads', \
       $city_labels using 1:2:3 with labels left font ',10' notitle
  set title 'random towns (3)'
  plot $rnd_front using 1:2 with steps lw 2 lc rgb '#2ca02c' title 'Pareto front', \
       $rnd_labels using 1:2:($4 - $1):($6 > 0 ? $5 - $2 : 1/0) with vectors nohead lc rgb '#aaaaaa' notitle, \
       $rnd using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps psz lc rgb '#1f77b4' title '1 thread', \
       $rnd using 1:($3 == 2 ? $2 : 1/0) with points pt 9 ps psz * 1.15 lc rgb '#d62728' title '2 threads', \
       $rnd_labels using 1:2:3 with labels left font ',10' notitle
  unset multiplot
  set output
}
