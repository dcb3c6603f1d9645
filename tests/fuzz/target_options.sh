# The libFuzzer options of each target, for run.sh and campaign.sh: `target_options NAME` prints them, one a line.
# Needs $here (tests/fuzz).
#  -dict    the target's dictionary (tests/fuzz/dict/).
#  -detect_leaks=0 for the targets with a running kernel or server threads: their threads allocate while an input
#           runs, so libFuzzer would stop the world for a leak scan after nearly every input (a 20x slowdown
#           measured on action_bodies); LeakSanitizer still checks the whole process when the run ends.
#  -entropic=0 for the same targets: the kernel's threads run instrumented code during every input, so each run
#           brings ~100,000 features and the entropic schedule's bookkeeping (InputCorpus::UpdateFeatureFrequency,
#           65% of the time in perf) cut action_bodies to 6 executions a second; without it, 224 a second.
#           Not yet for ws_frames: at 64 inputs a second its harness waited past libFuzzer's 20 s timeout for the
#           answer to its marker message (it relies on the robot's R2R refusal answers, which are rate-limited).
target_options() {
  case "$1" in
    http_request) echo "-dict=$here/dict/http.dict" ;;
    json_bodies | action_bodies | manifest) echo "-dict=$here/dict/json.dict" ;;
    rcan_yaml | swarm_yaml | conf_d) echo "-dict=$here/dict/yaml.dict" ;;
    r2r_envelope | ws_frames) echo "-dict=$here/dict/r2r.dict" ;;
    model_answer) echo "-dict=$here/dict/model.dict" ;;
    dynamixel_status) echo "-dict=$here/dict/dynamixel.dict" ;;
    driver_settings) echo "-dict=$here/dict/drivers.dict" ;;
  esac
  case "$1" in
    http_request | json_bodies | action_bodies | ws_frames | model_answer) echo "-detect_leaks=0" ;;
  esac
  case "$1" in
    http_request | json_bodies | action_bodies | ws_frames | model_answer) echo "-entropic=0" ;;
  esac
}
