# Included by ctest after the discovered gtest tests: labels the tests on ../shared/meshes.
foreach(_t RofiAutoFandisk RofiAutoBlock RofiAutoTwelveImpulsive RofiAutoSharpSphere
           RofiTunedFandisk RofiTunedSharpSphere EnvtAutoFandisk BilateralFandisk)
  set_tests_properties(SharedMeshes.${_t} PROPERTIES LABELS slow)
endforeach()
# VTK's ICP runs hundreds of iterations per registration (tests/mesh/meanshape_test.cpp).
set_tests_properties(Icp.RecoversKnownRotations MeanShape.RigidCopiesGiveTheOriginalWithZeroSd
  MeanShape.CommandWritesMeanWithSdAndReportsIcpResiduals PROPERTIES LABELS slow)
# Ten denoisings of the 6345-point noisy cube (tests/mesh/pointset_test.cpp), ~2.5 s Release.
set_tests_properties(PointSet.CubeEdgesOverSeedsShiftedAgainstPcaNormals PROPERTIES LABELS slow)
# The hostile-mesh campaign runs octshape 99 times (33 files x denoise, metrics, features):
# ~6 s alone, ~18 s on a loaded machine (tests/mesh/mesh_campaign_test.cpp).
set_tests_properties(MeshCampaign.HostileFilesGiveTypedErrorsOrFiniteResults PROPERTIES LABELS slow)
